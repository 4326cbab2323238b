// A request id for a change (docs/api.md "Retries"): the server answers a repeat of it as it
// answered the first, so a retry after a lost answer never applies the change twice.
// getRandomValues, not randomUUID: the latter exists only in secure contexts (https, localhost).
export function newRequestId(): string {
  const bytes = crypto.getRandomValues(new Uint8Array(16));
  return Array.from(bytes, (b) => b.toString(16).padStart(2, "0")).join("");
}
