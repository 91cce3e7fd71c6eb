# Sourced by scripts/viewer-screenshot.sh and scripts/live-view-screenshot.sh (from the
# repository's root): checks LICHTBLICK_WEB, and installs what the screenshot needs, each once:
# Debian's chromium ($CHROMIUM, /usr/bin/chromium by default) and scripts/viewer's pinned
# playwright-core.
: "${LICHTBLICK_WEB:?set LICHTBLICK_WEB to a Lichtblick web build (the directory with its index.html)}"
if [ ! -f "$LICHTBLICK_WEB/index.html" ]; then
  echo "no index.html in LICHTBLICK_WEB=$LICHTBLICK_WEB" >&2
  exit 1
fi
CHROMIUM=${CHROMIUM:-/usr/bin/chromium}
if [ ! -x "$CHROMIUM" ]; then
  echo "== installing chromium (apt)"
  apt-get update -q
  DEBIAN_FRONTEND=noninteractive apt-get install -y -q chromium
fi
if [ ! -f scripts/viewer/node_modules/playwright-core/package.json ]; then
  echo "== installing playwright-core (npm)"
  (cd scripts/viewer && PLAYWRIGHT_SKIP_BROWSER_DOWNLOAD=1 npm install --no-audit --no-fund --no-package-lock)
fi
