import { defineConfig } from "vite";

// `npm run dev` serves the viewer with hot reload and proxies the API to a running
// hdeform-server's HTTP port (HDEFORM_HTTP, default http://127.0.0.1:8080).
const api = process.env.HDEFORM_HTTP ?? "http://127.0.0.1:8080";

export default defineConfig({
  base: "./",
  build: { outDir: "dist", emptyOutDir: true, chunkSizeWarningLimit: 1500, sourcemap: false },
  server: {
    proxy: {
      "/hdeform.v1.Deformation": { target: api, changeOrigin: false },
      "/upload": { target: api, changeOrigin: false },
    },
  },
});
