// Random ids the viewer chooses: session ids, its client identity, and request ids for
// changes (docs/api.md "Retries": the server answers a repeat of a request id as it answered
// the first, so a retry after a lost answer never applies the change twice).
// getRandomValues, not randomUUID: the latter exists only in secure contexts (https, localhost).
export function randomHex(bytes: number): string {
  return Array.from(crypto.getRandomValues(new Uint8Array(bytes)), (b) => b.toString(16).padStart(2, "0")).join("");
}

export function newRequestId(): string {
  return randomHex(16);
}
