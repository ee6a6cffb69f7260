#!/usr/bin/env bash
# Renders a glassbake report (report/index.html) in headless Chromium and saves a full-page
# screenshot, to check that the self-contained page renders without network access.
#
#   tools/report-screenshot/screenshot.sh bake/report/index.html report.png [WIDTH] [HEIGHT]
#
# Installs Debian's chromium if it is missing (needs apt and root or sudo).
set -euo pipefail
page="$(realpath "$1")"
out="$(realpath -m "$2")"
width="${3:-1280}"
height="${4:-4000}"
if ! command -v chromium >/dev/null 2>&1; then
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends chromium
fi
profile="$(mktemp -d)"
trap 'rm -rf "$profile"' EXIT
# No network and no background services: the page must need neither.
chromium --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
  --disable-background-networking --disable-component-update --disable-sync \
  --user-data-dir="$profile" --hide-scrollbars --window-size="${width},${height}" \
  --screenshot="$out" "file://$page" 2>/dev/null
echo "screenshot of $page: $out"
