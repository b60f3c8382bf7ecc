// Vite builds the page into one folder that hwr-ground serves (toolchain/build-web.sh sets outDir).
import { defineConfig } from 'vite';

export default defineConfig({
  base: './',
  build: { chunkSizeWarningLimit: 1000 },
});
