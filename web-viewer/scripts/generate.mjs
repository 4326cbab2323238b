// Generates the TypeScript stubs for proto/hdeform/v1/*.proto into src/gen/ with protoc
// (Debian's protobuf-compiler, ≥ 3.15) and @bufbuild/protoc-gen-es (which also emits the
// service descriptor that @connectrpc/connect's createClient needs). src/gen is not committed.
import { execFileSync } from "node:child_process";
import { mkdirSync, readdirSync, rmSync } from "node:fs";
import { dirname, join, resolve } from "node:path";
import { fileURLToPath } from "node:url";

const here = dirname(fileURLToPath(import.meta.url));
const viewer = resolve(here, "..");
const protoRoot = resolve(viewer, "../proto");
const out = join(viewer, "src/gen");
const plugin = join(viewer, "node_modules/.bin/protoc-gen-es");
const protoc = process.env.PROTOC || "protoc";

const protos = readdirSync(join(protoRoot, "hdeform/v1"))
  .filter((f) => f.endsWith(".proto"))
  .map((f) => `hdeform/v1/${f}`);

rmSync(out, { recursive: true, force: true });
mkdirSync(out, { recursive: true });
try {
  execFileSync(
    protoc,
    [`--plugin=protoc-gen-es=${plugin}`, `--es_out=${out}`, "--es_opt=target=ts", `-I${protoRoot}`, ...protos],
    { stdio: "inherit" },
  );
} catch (e) {
  console.error(`generate: ${protoc} failed (${e.message}). Install protobuf-compiler (scripts/install-deps.sh) or set PROTOC.`);
  process.exit(1);
}
console.log(`generate: ${protos.join(", ")} → src/gen`);
