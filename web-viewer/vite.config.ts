import { defineConfig } from "vite";

// `npm run dev` serves the viewer with hot reload and proxies the API to a running
// hdeform-server's HTTP port (HDEFORM_HTTP, default http://127.0.0.1:8080).
const api = process.env.HDEFORM_HTTP ?? "http://127.0.0.1:8080";

// `vite build --mode test` (npm run build:test, the browser tests) builds the page with its test
// hook (window.hdeform) into dist-test; the production build (dist) has no hook.
export default defineConfig(({ mode }) => ({
  base: "./",
  build: { outDir: mode === "test" ? "dist-test" : "dist", emptyOutDir: true, chunkSizeWarningLimit: 1500, sourcemap: false },
  server: {
    proxy: {
      "/hdeform.v1.Deformation": { target: api, changeOrigin: false },
      "/upload": { target: api, changeOrigin: false },
    },
  },
}));
