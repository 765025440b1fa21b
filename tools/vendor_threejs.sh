#!/bin/sh
# Vendor the pinned three.js files used by the HTML report into apps/report_assets/three/.
# Needs npm (registry access) once, at build time; the report itself never touches the network.
# Usage: tools/vendor_threejs.sh [VERSION]   (default: the pinned version below)
set -eu
VERSION="${1:-0.169.0}"
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
DEST="$ROOT/apps/report_assets/three"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
(cd "$WORK" && npm pack --silent "three@$VERSION" >/dev/null && tar xzf "three-$VERSION.tgz")
P="$WORK/package"
mkdir -p "$DEST"
cp "$P/build/three.module.min.js" "$DEST/three.module.min.js"
cp "$P/examples/jsm/controls/OrbitControls.js" "$DEST/OrbitControls.js"
cp "$P/examples/jsm/loaders/GLTFLoader.js" "$DEST/GLTFLoader.js"
cp "$P/examples/jsm/utils/BufferGeometryUtils.js" "$DEST/BufferGeometryUtils.js"
cp "$P/LICENSE" "$DEST/LICENSE"
printf '%s\n' "$VERSION" > "$DEST/VERSION"
(cd "$DEST" && sha256sum three.module.min.js OrbitControls.js GLTFLoader.js BufferGeometryUtils.js LICENSE > SHA256SUMS)
echo "three@$VERSION vendored into $DEST"
cat "$DEST/SHA256SUMS"
