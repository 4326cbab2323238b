// Issue 37's rule, checked on the sources: every Deformation method is either a mutation or a
// read (a new RPC needs a decision), and no module outside src/commands/ calls a mutating method
// of the client: they go through the command layer (app.edits.execute). test_hook.ts's generic
// call() (test builds only) stands in for another program and calls by name, which is no
// `client.method(` either.
import assert from "node:assert/strict";
import { readdirSync, readFileSync } from "node:fs";
import { join, relative } from "node:path";
import { describe, it } from "node:test";
import { fileURLToPath } from "node:url";
import { MUTATING_METHODS, READ_METHODS } from "../src/commands/methods";
import { Deformation } from "../src/gen/hdeform/v1/deform_pb";

const SRC = fileURLToPath(new URL("../src/", import.meta.url));
const LAYER = "commands/";
const camel = (s: string) => s[0].toLowerCase() + s.slice(1);
// `client.setBeta(`, `this.client.undo (`, `client["setTimeline"]`, `client?.redo(`
const direct = new RegExp(String.raw`\bclient\s*\??\.\s*(${MUTATING_METHODS.join("|")})\s*\(|\bclient\s*\[\s*["'\x60](${MUTATING_METHODS.join("|")})["'\x60]`, "g");

function sources(): string[] {
  return (readdirSync(SRC, { recursive: true }) as string[])
    .map((f) => f.split("\\").join("/"))
    .filter((f) => f.endsWith(".ts") && !f.startsWith("gen/"));
}

describe("one command layer", () => {
  it("every Deformation method is a mutation or a read, not both", () => {
    const methods = Object.values(Deformation.method).map((m) => camel(m.name));
    const listed = [...MUTATING_METHODS, ...READ_METHODS] as string[];
    assert.deepEqual([...listed].sort(), [...methods].sort());
    assert.equal(new Set(listed).size, listed.length);
  });
  it("the scan finds a direct mutating call (it is not vacuous)", () => {
    const sample = `await client.undo({}); await this.client.grabHandles(r); client["setBeta"](r); client.getSession(r); clientId.setBeta(x);`;
    assert.deepEqual([...sample.matchAll(direct)].map((m) => m[1] ?? m[2]), ["undo", "grabHandles", "setBeta"]);
  });
  it("no module outside src/commands/ calls a mutating client method", () => {
    const files = sources();
    assert.ok(files.length > 50, `found ${files.length} sources`);
    const offenders: string[] = [];
    for (const f of files) {
      if (f.startsWith(LAYER)) continue;
      const text = readFileSync(join(SRC, f), "utf8");
      for (const m of text.matchAll(direct)) {
        const line = text.slice(0, m.index).split("\n").length;
        offenders.push(`${relative(SRC, join(SRC, f))}:${line}: ${m[0]}`);
      }
    }
    assert.deepEqual(offenders, [], "go through app.edits.execute (src/commands/command_layer.ts)");
  });
});
