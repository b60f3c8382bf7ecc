#!/usr/bin/env bash
# Builds hwr-ground's viewer page (apps/hwr-ground/web: three.js, bundled by Vite) into
# build/web/dist, which `hwr-ground --http` serves (docs/ground_viewer.md). The npm packages come
# from the npm registry, pinned by package-lock.json (`npm ci`), and are installed again only when
# the lock file changed; the page is built again only when a source changed. No CDN at run time.
# Usage: toolchain/build-web.sh
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
web=apps/hwr-ground/web
dist=build/web/dist

if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
  echo "build-web: node and npm are needed: run ./toolchain/install-deps.sh --with-web" >&2
  exit 1
fi
# Vite 6 and playwright-core 1.60 (package.json) run on Node.js 18 (Debian 12's nodejs) and later.
if ! node -e 'process.exit(Number(process.versions.node.split(".")[0]) >= 18 ? 0 : 1)'; then
  echo "build-web: Node.js $(node --version) is too old: the page's build (Vite 6) needs 18 or later" >&2
  exit 1
fi
# npm ci records what it installed in node_modules/.package-lock.json.
if [[ ! -f "$web/node_modules/.package-lock.json" || "$web/package-lock.json" -nt "$web/node_modules/.package-lock.json" ]]; then
  echo "build-web: installing the page's npm packages (npm ci)"
  (cd "$web" && npm ci --no-audit --no-fund --loglevel=error)
fi
stamp="$dist/index.html"
if [[ -f "$stamp" ]] && [[ -z "$(find "$web/index.html" "$web/vite.config.js" "$web/package.json" "$web/src" "$web/node_modules/.package-lock.json" -newer "$stamp" -print -quit)" ]]; then
  echo "build-web: $dist is up to date"
  exit 0
fi
mkdir -p "$dist"
(cd "$web" && npx --no-install vite build --logLevel warn --outDir "$(realpath -m "../../../$dist")" --emptyOutDir)
echo "build-web: the page is in $dist (hwr-ground --http serves it)"
