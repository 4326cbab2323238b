// The ★ library models' benchmark regions (data/botsch-sorkine/NAME.sel), bundled with the
// viewer: the API has no call that hands out a library mesh's .sel, and the viewer should
// show the regions as regions (labels it can edit), not only send them. Each file is its own
// chunk, fetched when that model is opened with its regions.
import { parseSel, type SelRegions } from "./sel_file";

const files = import.meta.glob<string>("../../data/botsch-sorkine/*.sel", { query: "?raw", import: "default" });

function key(name: string): string | undefined {
  return Object.keys(files).find((k) => k.endsWith(`/${name}.sel`));
}

export function hasBundledRegions(name: string): boolean {
  return key(name) !== undefined;
}

export async function bundledRegions(name: string, vertexCount: number): Promise<SelRegions> {
  const k = key(name);
  if (!k) throw new Error(`no benchmark regions bundled for ${name}`);
  return parseSel(await files[k](), vertexCount);
}
