#!/usr/bin/env bash
# Rebuild three.min.js from the npm package three@0.187.0 (needs node/npm; fetches from npm).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
npm pack three@0.187.0 >/dev/null
tar xzf three-0.187.0.tgz
sed -i "s#from 'three'#from '../../../build/three.module.js'#" package/examples/jsm/controls/OrbitControls.js
cat > entry.js <<'JS'
export * from './package/build/three.module.js';
export { OrbitControls } from './package/examples/jsm/controls/OrbitControls.js';
JS
npx -y esbuild@0.24.0 entry.js --bundle --minify --format=esm --legal-comments=eof \
  --outfile="$here/three.min.js"
cp package/LICENSE "$here/LICENSE.three"
