"""The physical mode: exact transfer-matrix optics of the rod stack as effective-medium slices.

Each horizontal slab of the rod lattice (:meth:`RodLattice.cells`: an area-preserving staircase,
about 16 slabs per rod diameter) is replaced by a homogeneous *uniaxial* slab whose permittivities
are the zeroth-order effective medium of its chords (Rytov 1956; Born & Wolf §15.5.2), melanin
share ``f_r``, air share ``f_a``, matrix the rest:

    ε_∥  = f_r ε_rod + f_a ε_air + (1 − f_r − f_a) ε_matrix           (E along the rods, y; and z)
    1/ε_⊥ = f_r / ε_rod + f_a / ε_air + (1 − f_r − f_a) / ε_matrix    (E across the rods in a slab, x)

which is the long-wavelength limit of the rigorous solution (:mod:`pavonine.materials.rcwa` with
one harmonic), so the rods' TE/TM anisotropy, their depth profile (round rods, not flat slabs) and
the overlap of staggered layers are all kept. The stack is solved with 2×2 characteristic matrices
(Born & Wolf §1.6.2; Yeh 1988 §4 for uniaxial layers), light in the ``x–z`` plane across the rods:

    TE (s, E ∥ rods):  k_z = √(ε_∥ − k_x²),             η = k_z
    TM (p, H ∥ rods):  k_z = √(ε_⊥ (1 − k_x²/ε_∥)),     η = ε_⊥ / k_z

(``k_x = n_above sin θ``, wavenumbers in units of ``k₀ = 2π/λ``), phase thickness ``δ = k_z k₀ h``,
``M = [[cos δ, −i sin δ/η], [−i η sin δ, cos δ]]`` and ``r = (η₀B − C)/(η₀B + C)`` with
``[B, C] = M [1, η_s]``. Unpolarised reflectance is the mean of TE and TM. The bulk cells repeat,
so their matrix is raised to a power (``N`` costs ``log N`` products).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import numpy as np

from pavonine.materials.arraymath import bilinear_gather
from pavonine.materials.lattice import RodLattice, Slice


def _slab_permittivities(piece: Slice, period: float, eps_rod, eps_matrix, tm_rule: str):
    """``(ε_∥, ε_⊥, ε_z)`` of one slab's chords (arrays over the wavelength axis).

    ``ε_∥`` (E along the rods) is the arithmetic mean, the exact long-wavelength limit. Across the
    rods the two Wiener bounds are the arithmetic and the harmonic mean; the harmonic one is exact
    only for flat lamellae (one-harmonic RCWA, ``tm_rule="lamellar"``). Round rods are neither, and
    ``tm_rule="dykhne"`` takes the geometric mean of the two bounds, which for two phases of equal
    share is Dykhne's exact 2-D result √(ε₁ε₂) (Dykhne 1971, Sov. Phys. JETP 32:63; Keller 1964),
    isotropic in the cross-section (``ε_z = ε_⊥``).
    """
    f_rod, f_air = piece.fractions(period)
    f_matrix = 1.0 - f_rod - f_air
    parallel = f_rod * eps_rod + f_air + f_matrix * eps_matrix
    harmonic = 1.0 / (f_rod / eps_rod + f_air + f_matrix / eps_matrix)
    if tm_rule == "lamellar":
        return parallel, harmonic, parallel
    if tm_rule != "dykhne":
        raise ValueError(f"tm_rule must be 'dykhne' or 'lamellar', got {tm_rule!r}")
    across = np.sqrt(parallel * harmonic)
    return parallel, across, across


def _matrix(eps_par, eps_perp, kx2, k0h, polarisation, eps_z=None):
    """Characteristic matrix (``m11, m12, m21, m22``) of one uniaxial slab (``ε_z`` defaults to
    ``ε_∥``: E_z along the slab's chord faces)."""
    eps_z = eps_par if eps_z is None else eps_z
    if polarisation == "TE":
        kz = np.sqrt(eps_par - kx2 + 0j)
        eta = kz
    else:
        kz = np.sqrt(eps_perp * (1.0 - kx2 / eps_z) + 0j)
        eta = eps_perp / np.where(kz == 0, 1e-30, kz)
    delta = kz * k0h
    c, s = np.cos(delta), np.sin(delta)
    return c, -1j * s / eta, -1j * eta * s, c


def _mul(a, b):
    return (
        a[0] * b[0] + a[1] * b[2],
        a[0] * b[1] + a[1] * b[3],
        a[2] * b[0] + a[3] * b[2],
        a[2] * b[1] + a[3] * b[3],
    )


def _power(m, count: int):
    result = None
    while count:
        if count & 1:
            result = m if result is None else _mul(result, m)
        count >>= 1
        if count:
            m = _mul(m, m)
    return result


def _admittance(eps, kx2, polarisation):
    kz = np.sqrt(eps - kx2 + 0j)
    kz = np.where(kz.imag < 0, -kz, kz)
    return kz if polarisation == "TE" else eps / np.where(kz == 0, 1e-30, kz)


def _reflectance(total, eps_above, eps_below, kx2, polarisation) -> np.ndarray:
    """``|r|²`` of a characteristic matrix between two half-spaces."""
    eta_above = _admittance(eps_above, kx2, polarisation)
    eta_below = _admittance(eps_below, kx2, polarisation)
    b = total[0] + total[1] * eta_below
    c = total[2] + total[3] * eta_below
    r = (eta_above * b - c) / (eta_above * b + c)
    return np.abs(r) ** 2


def uniaxial_stack_reflectance(
    slabs: Sequence[tuple],
    wavelength_nm: np.ndarray,
    *,
    n_above,
    n_below,
    sin_above: np.ndarray | float = 0.0,
    polarisation: str = "TE",
) -> np.ndarray:
    """``|r|²`` of planar uniaxial slabs ``(ε_∥, ε_⊥, thickness_nm)`` listed from the top.

    The characteristic-matrix solver the physical mode runs on; an isotropic layer has
    ``ε_∥ = ε_⊥ = n²``. ``polarisation`` is ``"TE"`` or ``"TM"``.
    """
    lam = np.asarray(wavelength_nm, dtype=np.float64)
    eps_above = np.asarray(n_above, dtype=np.complex128) ** 2
    kx2 = (np.sqrt(eps_above).real * np.asarray(sin_above, dtype=np.float64)) ** 2 + 0j
    k0 = 2.0 * math.pi / lam
    total = (1.0 + 0j, 0j, 0j, 1.0 + 0j)
    for par, perp, thickness in slabs:
        total = _mul(total, _matrix(par, perp, kx2, k0 * thickness, polarisation))
    eps_below = np.asarray(n_below, dtype=np.complex128) ** 2
    return _reflectance(total, eps_above, eps_below, kx2, polarisation)


def lattice_reflectance_emt(
    lattice: RodLattice,
    wavelength_nm: np.ndarray,
    *,
    n_rod,
    n_matrix,
    n_above=None,
    sin_above: np.ndarray | float = 0.0,
    polarisation: str = "unpolarised",
    per_diameter: int = 16,
    tm_rule: str = "dykhne",
) -> np.ndarray:
    """Reflectance of the stack (cortex included) by the effective-medium transfer matrix.

    Broadcasts over ``wavelength_nm`` and ``sin_above`` (sine of the incidence angle in the medium
    above, index ``n_above``; default: the matrix). Indices may be complex and arrays over λ.
    ``tm_rule``: effective permittivity across the rods (:func:`_slab_permittivities`).
    """
    if polarisation == "unpolarised":
        args = dict(
            n_rod=n_rod,
            n_matrix=n_matrix,
            n_above=n_above,
            sin_above=sin_above,
            per_diameter=per_diameter,
            tm_rule=tm_rule,
        )
        te = lattice_reflectance_emt(lattice, wavelength_nm, polarisation="TE", **args)
        tm = lattice_reflectance_emt(lattice, wavelength_nm, polarisation="TM", **args)
        return 0.5 * (te + tm)
    lam = np.asarray(wavelength_nm, dtype=np.float64)
    eps_rod = np.asarray(n_rod, dtype=np.complex128) ** 2
    eps_matrix = np.asarray(n_matrix, dtype=np.complex128) ** 2
    eps_above = eps_matrix if n_above is None else np.asarray(n_above, np.complex128) ** 2
    kx2 = (np.sqrt(eps_above).real * np.asarray(sin_above, dtype=np.float64)) ** 2 + 0j
    k0 = 2.0 * math.pi / lam
    period = lattice.check().period

    def chain(pieces: Sequence[Slice]):
        out = None
        for piece in pieces:
            par, perp, z = _slab_permittivities(piece, period, eps_rod, eps_matrix, tm_rule)
            m = _matrix(par, perp, kx2, k0 * piece.thickness, polarisation, z)
            out = m if out is None else _mul(out, m)
        return out

    cells = lattice.cells(per_diameter)
    parts = []
    if lattice.cortex > 0.0:
        parts.append(_matrix(eps_matrix, eps_matrix, kx2, k0 * lattice.cortex, polarisation))
    parts.append(chain(cells.top))
    if cells.n_bulk:
        parts.append(_power(chain(cells.bulk[0]), cells.n_bulk))  # ε is shift-invariant
    if cells.bottom:
        parts.append(chain(cells.bottom))
    total = parts[0]
    for part in parts[1:]:
        total = _mul(total, part)
    return _reflectance(total, eps_above, eps_matrix, kx2, polarisation)


# --------------------------------------------------------------------------- tables for the BSDF

#: Wavelength grid of the tables (nm): Mitsuba's spectral range, 4 nm apart.
TABLE_WAVELENGTHS_NM = (360.0, 832.0, 119)
#: Internal-angle samples (cosines from the critical angle to normal incidence).
TABLE_ANGLES = 64
#: Gradation samples per class and axis when the two gradation ends differ.
TABLE_GRADATIONS = 5


def structure_reflectance(
    stack,
    arrangement: str,
    cortex_um: float,
    wavelength_nm: np.ndarray,
    cos_inside: np.ndarray,
    melanin,
    keratin,
) -> np.ndarray:
    """Unpolarised reflectance of a barbule from air: cortex + rod layers + keratin below.

    ``stack`` is a :class:`~pavonine.materials.parameters.LayerStack` (µm); a non-integer layer
    count interpolates linearly between ⌊N⌋ and ⌈N⌉ layers. ``cos_inside`` is the cosine of the
    angle inside the cortex (the matrix above the rods); directions it cannot be reached at from
    air are evaluated at grazing incidence. Broadcasts ``wavelength_nm`` against ``cos_inside``.
    """
    lam = np.asarray(wavelength_nm, dtype=np.float64)
    n_top = keratin.real(lam)
    sin_inside = np.sqrt(np.clip(1.0 - np.asarray(cos_inside, dtype=np.float64) ** 2, 0.0, 1.0))
    sin_air = np.minimum(n_top * sin_inside, 1.0)
    kwargs = dict(n_rod=melanin.index(lam), n_matrix=n_top, n_above=1.0, sin_above=sin_air)
    low = max(math.floor(stack.count), 1)
    t = float(stack.count) - low
    r_low = lattice_reflectance_emt(stack.lattice(arrangement, cortex_um, low), lam, **kwargs)
    if t <= 1e-6:
        return r_low
    r_high = lattice_reflectance_emt(stack.lattice(arrangement, cortex_um, low + 1), lam, **kwargs)
    return r_low + (r_high - r_low) * t


@functools.lru_cache(maxsize=256)
def _table_plane(stack, arrangement: str, cortex_um: float, melanin, keratin, grid) -> np.ndarray:
    """One table entry: the structure's reflectance on the table's (λ, cos θ_inside) grid,
    float32 in [0, 1]. Cached per structure, so the two axes of a class, and materials sharing a
    class (the shipped feathers), compute each structure once per process."""
    lam0, dlam, n_lam, cos0, dcos, n_cos = grid
    lam = lam0 + dlam * np.arange(n_lam)
    cos_in = cos0 + dcos * np.arange(n_cos)
    values = structure_reflectance(
        stack, arrangement, cortex_um, lam[:, None], cos_in[None, :], melanin, keratin
    )
    plane = np.clip(values, 0.0, 1.0).astype(np.float32)
    plane.flags.writeable = False
    return plane


class StackTable:
    """Physical-mode reflectance of every class, axis and gradation sample, on (λ, cos θ_inside).

    ``values`` is flat, row-major ``[entry, λ, cos]`` with ``entry = (class·A + axis)·K + k``,
    ``K`` gradation samples per axis (1 when the material's gradation ends are equal) and ``A``
    axes per class: 2, or 1 when every class has the same structure along both axes
    (:attr:`shared_axes`, as in ``freyer2020``), which halves the lookups. Built once per
    material; :meth:`lookup` interpolates it on NumPy and Dr.Jit alike (the renderer and the
    analysis model read the same numbers).
    """

    def __init__(self, params, values=None):
        from pavonine.materials.parameters import AXES

        lo, hi, n_lam = TABLE_WAVELENGTHS_NM
        self.lam0, self.n_lam = lo, n_lam
        self.dlam = (hi - lo) / (n_lam - 1)
        n_min = float(np.min(params.keratin.real(np.linspace(lo, hi, n_lam))))
        self.cos0 = math.sqrt(max(1.0 - 1.0 / (n_min * n_min), 0.0))
        self.n_cos = TABLE_ANGLES
        self.dcos = (1.0 - self.cos0) / (self.n_cos - 1)
        same = all(
            getattr(c, axis)[0] == getattr(c, axis)[1] and c.cortex[0] == c.cortex[1]
            for c in params.classes
            for axis in AXES
        )
        self.k = 1 if same else TABLE_GRADATIONS
        #: Every class is one structure along both barbule axes: one entry serves both.
        self.shared_axes = all(c.long == c.short for c in params.classes)
        self.axes = 1 if self.shared_axes else 2
        self.keratin_a = float(params.keratin.cauchy_a)
        self.keratin_b = float(params.keratin.cauchy_b)
        if values is None:
            values = self._build(params)
        self.values = values

    def _build(self, params) -> np.ndarray:
        gradations = np.linspace(0.0, 1.0, self.k) if self.k > 1 else np.zeros(1)
        grid = (self.lam0, self.dlam, self.n_lam, self.cos0, self.dcos, self.n_cos)
        planes = [
            _table_plane(
                cls.at(t)[axis],
                params.lattice,
                cls.cortex_at(t),
                params.melanin,
                params.keratin,
                grid,
            )
            for cls in params.classes
            for axis in range(self.axes)
            for t in gradations
        ]
        return np.stack(planes).ravel()

    def with_values(self, values) -> StackTable:
        """The same table with its values in another array type (a Dr.Jit buffer)."""
        clone = object.__new__(StackTable)
        clone.__dict__.update(self.__dict__)
        clone.values = values
        return clone

    def cos_inside(self, wavelength_nm, cos_outside, ops):
        """Snell's law into the cortex: ``cos θ_in = √(1 − sin²θ_out / n(λ)²)``."""
        n = self.keratin_a + self.keratin_b / (wavelength_nm * wavelength_nm)
        sin2 = (1.0 - cos_outside * cos_outside) / (n * n)
        return ops.sqrt(ops.maximum(1.0 - sin2, 0.0))

    def entry(self, ocellar_class, axis: int):
        """First table entry of a class and axis (a float, for ``ops.gather``)."""
        return (ocellar_class * self.axes + min(axis, self.axes - 1)) * self.k

    def lookup(self, entry, gradation, wavelength_nm, cos_outside, ops):
        """Reflectance at an outside (air) angle: trilinear in gradation, λ and cos θ_inside."""
        cos_in = self.cos_inside(wavelength_nm, cos_outside, ops)
        fl = ops.minimum(
            ops.maximum((wavelength_nm - self.lam0) * (1.0 / self.dlam), 0.0), self.n_lam - 1.0001
        )
        fc = ops.minimum(
            ops.maximum((cos_in - self.cos0) * (1.0 / self.dcos), 0.0), self.n_cos - 1.0001
        )
        il, ic = ops.floor(fl), ops.floor(fc)
        tl, tc = fl - il, fc - ic
        per_entry = self.n_lam * self.n_cos

        def plane(index):
            base = index * per_entry + il * self.n_cos + ic
            return bilinear_gather(self.values, base, self.n_cos, tc, tl, ops)

        if self.k == 1:
            return plane(entry)
        fg = ops.minimum(ops.maximum(gradation * (self.k - 1.0), 0.0), self.k - 1.0001)
        ig = ops.floor(fg)
        lower = plane(entry + ig)
        upper = plane(entry + ig + 1.0)
        return lower + (upper - lower) * (fg - ig)
