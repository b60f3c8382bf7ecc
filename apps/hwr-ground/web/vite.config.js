// Vite builds the page into one folder that hwr-ground serves (toolchain/build-web.sh sets outDir).
// `npx vite` (a development server with reload on save) forwards the API to a running hwr-ground
// or dev/mock_server.mjs at HWR_GROUND_URL (default http://127.0.0.1:8080).
import { defineConfig } from 'vite';

export default defineConfig({
  base: './',
  build: { chunkSizeWarningLimit: 1000 },
  // changeOrigin: hwr-ground answers only requests whose Host is its own loopback address.
  server: { proxy: { '/api': { target: process.env.HWR_GROUND_URL || 'http://127.0.0.1:8080', changeOrigin: true } } },
});
