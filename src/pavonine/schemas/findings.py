"""Running every USD validator (USD's own and Pavonine's) on a stage: :func:`validate_stage`
returns one :class:`Finding` row per problem for ``pavonine validate``.

Importing this module imports :mod:`pavonine.schemas.validation` (Pavonine's validators, a USD
plugin), which needs the validator plugin registered before the first
``UsdValidation.ValidationRegistry()``: ``import pavonine`` does that.
"""

from __future__ import annotations

import contextlib
import functools
import re
from dataclasses import asdict, dataclass

from pxr import Tf, Usd, UsdValidation

from pavonine.base.native_output import silenced
from pavonine.schemas import validation
from pavonine.schemas.validation import ERROR


@dataclass(frozen=True)
class Finding:
    """One validation result: ``severity path field: message``."""

    severity: str  # "ERROR" | "WARNING"
    path: str  # prim path, or "/" for the layer/stage
    field: str  # attribute name, or the error's name when it is not about one attribute
    message: str
    validator: str
    file: str

    def line(self) -> str:
        return f"{self.severity} {self.path} {self.field}: {self.message}"

    def as_dict(self) -> dict[str, str]:
        return asdict(self)


def all_validators() -> list:
    """USD's registered validators plus Pavonine's, loaded through the registry."""
    registry = UsdValidation.ValidationRegistry()
    validators = list(registry.GetOrLoadAllValidators())
    names = {v.GetMetadata().name for v in validators}
    for name in validation.validator_names():
        if name not in names:
            validators.append(registry.GetOrLoadValidatorByName(name))
    return validators


def _finding(error, file: str) -> Finding:
    severity = "ERROR" if error.GetType() == ERROR else "WARNING"
    path, field = "/", validation.METADATA_FIELD.get(error.GetName(), error.GetName())
    for site in error.GetSites():
        if site.IsProperty():
            prop_path = site.GetProperty().GetPath()
            path, field = str(prop_path.GetPrimPath()), prop_path.name
            break
        if site.IsPrim():
            path = str(site.GetPrim().GetPath())
            break
        spec = site.GetPropertySpec() or site.GetPrimSpec()
        if spec:
            path = str(spec.path.GetPrimPath())
            if spec.path.IsPropertyPath():
                field = spec.path.name
            break
    validator = error.GetValidator()
    name = validator.GetMetadata().name if validator else ""
    message = " ".join(error.GetMessage().split())
    return Finding(severity, path, field, message, name, file)


#: USD validators whose verdict Pavonine adjusts (see :func:`_adjust_usd_findings`).
_SDR_VALIDATOR = "usdShadeValidators:ShaderSdrCompliance"
_SDR_LOOKUP = re.compile(r"shaderId '(ND_\w+)' .* not found in sdrRegistry")
_GEOM_METADATA = {"MissingUpAxisMetadata", "MissingMetersPerUnitMetadata"}


@functools.cache
def sdr_knows_materialx() -> bool:
    """True when USD's shader registry reads MaterialX node definitions (a USD build with
    ``usdMtlx``: a parser of source type ``mtlx``); usd-core has none. The shader definitions
    ``pavonine env`` puts on Sdr's search path (``schemas/shaderDefs``) do not count: they
    cover only the nodes a converted asset uses."""
    from pxr import Sdr

    return "mtlx" in Sdr.Registry().GetAllShaderNodeSourceTypes()


def _is_mtlx_lookup(finding: Finding) -> bool:
    """A ``ShaderSdrCompliance`` finding that Sdr cannot find a MaterialX node (``ND_…``)."""
    return finding.validator == _SDR_VALIDATOR and bool(_SDR_LOOKUP.search(finding.message))


def _adjust_usd_findings(stage: Usd.Stage, findings: list[Finding]) -> list[Finding]:
    """Two adjustments to USD's own findings, both documented in docs/schema.md:

    * usd-core ships no usdMtlx, so Sdr knows no MaterialX node definition and
      ``ShaderSdrCompliance`` rejects every MaterialX shader (``info:id = "ND_…"``): Pavonine's
      ``ND_pavonine_feather_surfaceshader`` and the standard nodes of the map-reading and
      portable networks alike (unless ``pavonine env``'s shader definitions are on Sdr's
      search path). Without usdMtlx those findings are dropped (``FeatherDerivedShaders``
      checks the feather shader against its ``.mtlx`` node definition instead); with usdMtlx
      they are kept (a missing ``PXR_MTLX_PLUGIN_SEARCH_PATHS``, say).
    * ``upAxis``/``metersPerUnit`` describe geometry; a layer without any (a material library)
      gets them as warnings rather than errors.
    """
    from pxr import UsdGeom

    has_geometry = any(UsdGeom.Boundable(p) for p in stage.Traverse())
    out = []
    for f in findings:
        if _is_mtlx_lookup(f) and not sdr_knows_materialx():
            continue
        if f.field in _GEOM_METADATA and not has_geometry and f.severity == "ERROR":
            f = Finding(
                "WARNING", f.path, f.field, f.message + " (no geometry here)", f.validator, f.file
            )
        out.append(f)
    return out


def quiet_usd_stderr() -> contextlib.AbstractContextManager[None]:
    """Silence USD's own diagnostic prints (TF_WARN) while validators run: what they say comes
    back as validation errors, reported in Pavonine's one-line form."""
    return silenced(2)


def validate_stage(stage: Usd.Stage, file: str | None = None) -> list[Finding]:
    """Every finding of USD's validators and Pavonine's on ``stage``, sorted by prim path."""
    file = file or stage.GetRootLayer().identifier
    validation.prepare(stage)
    validators = all_validators()
    failed: list[Finding] = []
    with quiet_usd_stderr():
        try:
            errors = list(UsdValidation.ValidationContext(validators).Validate(stage))
        except Tf.ErrorException:  # one validator choked (a truncated layer): run them one by one
            errors, failed = _validate_one_by_one(stage, validators, file)
    findings = [_finding(e, file) for e in errors if not e.HasNoError()] + failed
    findings = _adjust_usd_findings(stage, findings)
    unique = list(dict.fromkeys(findings))
    return sorted(unique, key=lambda f: (f.path, f.field, f.severity, f.message))


def _validate_one_by_one(stage: Usd.Stage, validators: list, file: str) -> tuple[list, list]:
    """USD's errors from every validator that runs, and one ERROR finding per validator that
    raised (a layer USD cannot read, such as a truncated ``.usdc`` payload), naming the cause."""
    errors: list = []
    failed: list[Finding] = []
    for validator in validators:
        try:
            errors.extend(UsdValidation.ValidationContext([validator]).Validate(stage))
        except Tf.ErrorException as exc:
            name = validator.GetMetadata().name
            failed.append(
                Finding("ERROR", "/", "ValidatorFailed", f"{name} could not run: "
                        f"{tf_message(exc)}", name, file)
            )  # fmt: skip
    return errors, failed


def tf_message(exc: Exception) -> str:
    """The first message of a ``Tf.ErrorException`` on one line (without C++ source locations)."""
    quoted = re.findall(r" : '(.*?)'\s*(?:\n|$)", str(exc), flags=re.S)
    text = quoted[0] if quoted else str(exc)
    return " ".join(text.split()) or type(exc).__name__


__all__ = ["Finding", "validate_stage"]
