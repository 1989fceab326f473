#!/usr/bin/env bash
# Is a PNG byte-stable across OpenColorIO releases? For each version given (default: every
# release that ships the pinned config), install it into its own virtual environment (over the
# current one's packages) and encode the same 285 536 scene-linear colours through every view of
# the pinned config, printing SHA-256 prefixes of the 8-bit and float results. Equal hashes on a
# row = bit-identical output. Not run by CI (it downloads each release); results in
# docs/compatibility.md.   Usage: .ci/ocio-patch-releases.sh [VERSION...]
set -euo pipefail
versions=("$@")
((${#versions[@]})) || versions=(2.5.0 2.5.1 2.5.2 2.6.0)
python=${PYTHON:-python3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cat >"$work/probe.py" <<'PY'
import hashlib
import numpy as np
import PyOpenColorIO as ocio
import sys
PINNED_CONFIG, DISPLAY, SCENE_LINEAR = sys.argv[1:4]
rng = np.random.default_rng(7)
x = np.concatenate([rng.uniform(0, 1, (200000, 3)), rng.uniform(0, 16, (20000, 3)),
                    np.linspace(0, 1, 65536)[:, None].repeat(3, 1)]).astype(np.float32)
config = ocio.Config.CreateFromFile(PINNED_CONFIG)
for view in config.getViews(DISPLAY):
    transform = ocio.DisplayViewTransform(src=SCENE_LINEAR, display=DISPLAY, view=view)
    y = x.copy()
    config.getProcessor(transform).getDefaultCPUProcessor().applyRGB(y)
    png = np.round(np.clip(y, 0, 1) * 255).astype(np.uint8)
    digest = [hashlib.sha256(a.tobytes()).hexdigest()[:12] for a in (png, y)]
    print(f"{ocio.__version__:8} {view:40} 8-bit {digest[0]}  float {digest[1]}")
PY
config=$("$python" -c 'from pavonine.materials.display import PINNED_CONFIG; print(PINNED_CONFIG)')
for version in "${versions[@]}"; do
    "$python" -m venv --system-site-packages "$work/v$version"
    "$work/v$version/bin/pip" install -q --no-deps --disable-pip-version-check "opencolorio==$version"
    "$work/v$version/bin/python" "$work/probe.py" "$config" "sRGB - Display" "Linear Rec.709 (sRGB)"
done
