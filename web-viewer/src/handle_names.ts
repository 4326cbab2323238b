// One handle numbering wherever a user reads: 0-based, as the server, the CLI, the History's
// summaries ("moved handle 0") and the server's error messages count them. Inside the page a
// region label h ≥ 1 is handle index h − 1 (label 0 is the fixed region); only these functions
// turn either into words.

/** "Handle 0" for handle index 0 (the first handle). */
export function handleName(index: number): string {
  return `Handle ${index}`;
}

/** "handle 0": the same, inside a sentence. */
export function handleWord(index: number): string {
  return `handle ${index}`;
}

/** The name of region label `label` (≥ 1: handle label − 1). */
export function labelName(label: number): string {
  return label === 0 ? "Fixed" : label < 0 ? "Erase" : handleName(label - 1);
}
