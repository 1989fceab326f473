"""``eval "$(pavonine env)"`` in a Python that has usd-core but cannot import pavonine: the schema
and its fallbacks are there, every USD validator loads, and UsdValidation finds nothing on a
converted asset: Sdr knows its MaterialX nodes from the shader definitions that ``pavonine env``
puts on Sdr's filesystem search path, although usd-core has no usdMtlx. Pavonine's validators are
opt-in (``--validators``), for Pythons that can import pavonine."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import textwrap

import pytest

from pavonine.apps.cli.env import SDR_EXTS_ENV_VAR, SDR_PATHS_ENV_VAR
from pavonine.materials.materialx import MTLX_PATH, NODEDEF
from pavonine.schemas import plugin

#: Run in the child before anything else: pavonine cannot be imported there.
BLOCK_PAVONINE = textwrap.dedent(
    """
    import importlib.abc, sys
    class _NoPavonine(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] == "pavonine":
                raise ModuleNotFoundError(f"No module named {name!r} (blocked by the test)")
    sys.meta_path.insert(0, _NoPavonine())
    """
)

PROBE = BLOCK_PAVONINE + textwrap.dedent(
    """
    import json, os, sys
    from pxr import Usd, UsdValidation
    try:
        import pavonine  # noqa: F401
        importable = True
    except ImportError:
        importable = False
    definition = Usd.SchemaRegistry().FindAppliedAPIPrimDefinition("PavonineFeatherAPI")
    out = {
        "pavonine_importable": importable,
        "schema": definition is not None,
        "fallback": definition.GetAttributeFallbackValue("pavonine:crescentSigma")
        if definition else None,
        "mtlx_paths": os.environ.get("PXR_MTLX_PLUGIN_SEARCH_PATHS", ""),
    }
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    out["validators"] = sorted(v.GetMetadata().name for v in validators)
    stage = Usd.Stage.Open(sys.argv[1])
    errors = UsdValidation.ValidationContext(validators).Validate(stage)
    out["errors"] = [
        {"validator": e.GetValidator().GetMetadata().name if e.GetValidator() else "",
         "name": e.GetName(), "message": " ".join(e.GetMessage().split())}
        for e in errors if not e.HasNoError()
    ]
    print(json.dumps(out))
    """
)

SDR_LOOKUP = re.compile(
    r"shaderId '(ND_\w+)' specified on shader prim <[^>]+> not found in sdrRegistry\."
)


def _clean_env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PXR_", "PYTHON"))}
    return env


def _run_with_env_lines(args: list[str], asset, probe: str = PROBE, drop=()) -> dict:
    """``eval "$(pavonine env ARGS)"`` in a shell (without the lines setting a variable in
    ``drop``), then a fresh ``python -I`` running ``probe``."""
    pavonine = [sys.executable, "-m", "pavonine.apps.cli", "env", *args]
    lines = subprocess.run(
        pavonine, capture_output=True, text=True, check=True, env=_clean_env()
    ).stdout
    lines = "\n".join(
        line for line in lines.splitlines() if not any(f" {name}=" in line for name in drop)
    )
    script = f'{lines}\nexec "{sys.executable}" -I -c "$PROBE" "$ASSET"\n'
    result = subprocess.run(
        ["sh", "-c", script],
        capture_output=True,
        text=True,
        env={**_clean_env(), "PROBE": probe, "ASSET": str(asset)},
        check=False,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    return json.loads(result.stdout.strip().splitlines()[-1])


def test_env_prints_the_schema_and_the_materialx_search_path():
    out = subprocess.run(
        [sys.executable, "-m", "pavonine.apps.cli", "env"],
        capture_output=True,
        text=True,
        check=True,
        env=_clean_env(),
    ).stdout.splitlines()
    assert out == [
        f"export PXR_PLUGINPATH_NAME={plugin.PLUGIN_DIR}",
        f"export PXR_MTLX_PLUGIN_SEARCH_PATHS={MTLX_PATH.parent}",
        f"export PXR_SDR_FS_PLUGIN_SEARCH_PATHS={plugin.SHADER_DEFS_DIR}",
        "export PXR_SDR_FS_PLUGIN_ALLOWED_EXTS=usda",
    ]
    with_validators = subprocess.run(
        [sys.executable, "-m", "pavonine.apps.cli", "env", "--validators"],
        capture_output=True,
        text=True,
        check=True,
        env={**_clean_env(), "PXR_PLUGINPATH_NAME": "/opt/other"},
    ).stdout.splitlines()
    assert with_validators[0] == (
        f"export PXR_PLUGINPATH_NAME=/opt/other{os.pathsep}{plugin.PLUGIN_DIR}"
        f"{os.pathsep}{plugin.VALIDATORS_DIR}"
    )
    # Sdr's extension list is appended to, not replaced (another studio's OSL shaders, say).
    other_exts = subprocess.run(
        [sys.executable, "-m", "pavonine.apps.cli", "env"],
        capture_output=True,
        text=True,
        check=True,
        env={**_clean_env(), SDR_EXTS_ENV_VAR: "oso"},
    ).stdout.splitlines()
    assert other_exts[-1] == f"export {SDR_EXTS_ENV_VAR}=oso{os.pathsep}usda"


def test_a_python_without_pavonine_loads_every_validator_and_finds_no_error(eye_asset):
    out = _run_with_env_lines([], eye_asset)
    assert out["pavonine_importable"] is False
    assert out["schema"] is True and out["fallback"] == 15.0
    assert str(MTLX_PATH.parent) in out["mtlx_paths"].split(os.pathsep)
    assert out["validators"] and not any(v.startswith("pavonine") for v in out["validators"])
    # usd-core has no usdMtlx: Sdr knows the asset's MaterialX nodes (Pavonine's and the standard
    # ones) only from the shader definitions on its filesystem search path.
    assert out["errors"] == []


def test_without_the_sdr_search_path_usd_core_cannot_find_the_materialx_nodes(eye_asset):
    """What the shader definitions fix: without them, ShaderSdrCompliance rejects every
    MaterialX shader of the asset, Pavonine's node and the standard ones alike."""
    out = _run_with_env_lines([], eye_asset, drop=(SDR_PATHS_ENV_VAR, SDR_EXTS_ENV_VAR))
    lookups = [SDR_LOOKUP.fullmatch(e["message"]) for e in out["errors"]]
    assert all(lookups) and out["errors"]
    assert {e["validator"] for e in out["errors"]} == {"usdShadeValidators:ShaderSdrCompliance"}
    ids = {m.group(1) for m in lookups}
    assert NODEDEF in ids and "ND_image_float" in ids and "ND_open_pbr_surface_surfaceshader" in ids


def test_validators_opt_in_loads_pavonines_validators_where_pavonine_is_importable(eye_asset):
    probe = PROBE.replace(BLOCK_PAVONINE, "")
    out = _run_with_env_lines(["--validators"], eye_asset, probe)
    names = {v for v in out["validators"] if v.startswith(plugin.VALIDATOR_PLUGIN_NAME)}
    assert len(names) == 4
    assert [e for e in out["errors"] if e["validator"].startswith("pavonine")] == []


@pytest.mark.skipif(shutil.which("sh") is None, reason="needs a POSIX shell")
def test_validators_plugin_in_a_python_without_pavonine_is_the_documented_failure(eye_asset):
    """Why validators are opt-in: a Python that cannot import pavonine must not get them."""
    lines = subprocess.run(
        [sys.executable, "-m", "pavonine.apps.cli", "env", "--validators"],
        capture_output=True,
        text=True,
        check=True,
        env=_clean_env(),
    ).stdout
    code = BLOCK_PAVONINE + (
        "from pxr import UsdValidation\nUsdValidation.ValidationRegistry().GetOrLoadAllValidators()\n"
    )
    result = subprocess.run(
        ["sh", "-c", f'{lines}\nexec "{sys.executable}" -I -c "$CODE"\n'],
        capture_output=True,
        text=True,
        env={**_clean_env(), "CODE": code},
        check=False,
        timeout=300,
    )
    assert result.returncode != 0 and "pavonine.schemas.validation" in result.stderr
