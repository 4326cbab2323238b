// Number boxes that show their value whole: enough significant digits, the exponent intact, and
// as wide as the text (a fixed width cut 0.99 to "0.9" and 3.57e-25 to "3.57e-2").

/** `v` with up to 6 significant digits, float noise dropped: 0.99 → "0.99", 3.57e-25 → "3.57e-25". */
export function faithful(v: number): string {
  return Number.isFinite(v) ? String(Number(v.toPrecision(6))) : String(v);
}

/**
 * Widens `input` to its text: digits are 1ch wide (other characters narrower), plus padding,
 * border and the spin buttons. Never narrower than `minCh` characters.
 */
export function fitToValue(input: HTMLInputElement, minCh: number): void {
  input.style.width = `calc(${Math.max(minCh, input.value.length)}ch + 34px)`;
}

/** Keeps `input` as wide as its text while the user types, too. */
export function autoFit(input: HTMLInputElement, minCh: number): () => void {
  const fit = () => fitToValue(input, minCh);
  input.addEventListener("input", fit);
  input.addEventListener("change", fit);
  fit();
  return fit;
}
