"""Rigorous coupled-wave analysis (RCWA) of the rod lattice: the exact reference for the physical mode.

The structure of :class:`pavonine.materials.lattice.RodLattice` is periodic along ``x`` (period
``L``) and invariant along the rods (``y``); light comes in the ``x–z`` plane, so TE (``E ∥ y``,
along the rods) and TM (``H ∥ y``) decouple (planar diffraction). Each horizontal slab of the
area-preserving staircase is expanded in ``2K + 1`` Fourier harmonics; in it the field is a sum of
eigenmodes of (``z' = k₀ z``, ``K_x = diag(k_x,m / k₀)``, ``[ε]`` and ``[1/ε]`` Toeplitz matrices of
the Fourier coefficients):

    TE:  d²S/dz'² = (K_x² − [ε]) S                                (Moharam et al. 1995, JOSA A 12:1068)
    TM:  d²U/dz'² = [1/ε]⁻¹ (K_x [ε]⁻¹ K_x − I) U                  (Li 1996, JOSA A 13:1870, inverse rule)

Slabs are joined with scattering matrices and Redheffer star products (Rumpf 2011, PIER B 35:241),
which stay stable for thick, absorbing stacks. The bulk of an ``N``-layer stack is one cell pair
raised to a power (``RodLattice.cells``). This module is a *reference*: it is used by tests and by
``pavonine figures``, never by the renderer.
"""

from __future__ import annotations

import numpy as np

from pavonine.materials.lattice import ROD, RodLattice, Slice


def _toeplitz(coefficients: np.ndarray, n: int) -> np.ndarray:
    """``T[..., m, k] = c[m − k]`` from coefficients ``c[−2K … 2K]`` stored at offset ``2K``."""
    idx = np.arange(n)[:, None] - np.arange(n)[None, :] + (n - 1)
    return coefficients[..., idx]


def _fourier(piece: Slice, period: float, values: dict[str, np.ndarray], base: np.ndarray, n: int):
    """Fourier coefficients (p = −2K…2K, shape (n_λ, 4K+1)) of the slab's profile ``values[kind]``."""
    p = np.arange(-(n - 1), n)
    g = 2.0 * np.pi * p / period
    out = np.zeros(base.shape + p.shape, dtype=np.complex128)
    out[..., n - 1] = base
    for s in piece.segments:
        shape = (2.0 * s.half_width / period) * np.sinc(g * s.half_width / np.pi)
        shape = shape * np.exp(-1j * g * s.centre)
        out += (values[s.kind] - base)[..., None] * shape
    return out


def _kz(eps: np.ndarray) -> np.ndarray:
    """``√ε`` on the branch with Im ≥ 0 (and Re ≥ 0 when real): outgoing or decaying along +z."""
    kz = np.sqrt(eps.astype(np.complex128))
    return np.where((kz.imag < 0) | ((kz.imag == 0) & (kz.real < 0)), -kz, kz)


class _Solver:
    """Eigenmodes and scattering matrices for one polarisation, batched over wavelengths."""

    def __init__(self, lattice, wavelengths, eps, eps_gap, kx0, harmonics, polarisation):
        self.period = lattice.period
        self.lam = wavelengths
        self.eps = eps
        self.n = 2 * harmonics + 1
        m = np.arange(-harmonics, harmonics + 1)
        self.kx = kx0[:, None] + m[None, :] * (wavelengths[:, None] / self.period)
        self.te = polarisation == "TE"
        self.eps_gap = eps_gap
        self.kz_gap = _kz(eps_gap[:, None] - self.kx**2)
        self.v_gap = self._v_uniform(self.kz_gap, eps_gap)

    def _v_uniform(self, kz, eps):
        return -kz if self.te else kz / eps[:, None]

    def modes(self, piece: Slice):
        """``(W, V, k_z)`` of a patterned slab (W: field, V: tangential partner field)."""
        n = self.n
        conv = _toeplitz(_fourier(piece, self.period, self.eps, self.eps["matrix"], n), n)
        kx2 = self.kx[:, :, None] * np.eye(n)
        kx = self.kx
        if self.te:
            omega2 = kx2 * kx[:, None, :] - conv
        else:
            inv_eps = {k: 1.0 / v for k, v in self.eps.items()}
            conv_inv = _toeplitz(_fourier(piece, self.period, inv_eps, inv_eps["matrix"], n), n)
            inner = kx[:, :, None] * np.linalg.solve(conv, kx2) - np.eye(n)
            omega2 = np.linalg.solve(conv_inv, inner)
        mu, w = np.linalg.eig(omega2)
        kz = _kz(-mu)
        if self.te:
            v = -w * kz[:, None, :]
        else:
            v = (conv_inv @ w) * kz[:, None, :]
        return w, v, kz

    def slab(self, piece: Slice):
        """Scattering matrix of a patterned slab (see :meth:`_slab`)."""
        modes = self.modes(piece) if piece.segments else self._uniform_modes(self.eps["matrix"])
        return self._slab(*modes, piece.thickness)

    def uniform_slab(self, eps: np.ndarray, thickness: float):
        """Scattering matrix of a homogeneous slab of permittivity ``eps`` (per wavelength)."""
        return self._slab(*self._uniform_modes(eps), thickness)

    def _uniform_modes(self, eps: np.ndarray):
        kz = _kz(eps[:, None] - self.kx**2)
        w = np.broadcast_to(np.eye(self.n), (*kz.shape, self.n)).astype(complex)
        return w, w * self._v_uniform(kz, eps)[:, None, :], kz

    def _slab(self, w, v, kz, thickness: float):
        """``(S11, S12, S21, S22)`` of a symmetric slab with modes ``(W, V, k_z)`` (Rumpf 2011,
        Eq. 36–39): ``A = W⁻¹W₀ + V⁻¹V₀``, ``B = W⁻¹W₀ − V⁻¹V₀``, ``X = exp(i k_z k₀ h)``."""
        x = np.exp(1j * kz * (2.0 * np.pi / self.lam[:, None]) * thickness)
        w_inv = np.linalg.inv(w)
        a = w_inv + np.linalg.inv(v) * self.v_gap[:, None, :]
        b = 2.0 * w_inv - a
        a_inv = np.linalg.inv(a)
        xb = x[:, :, None] * b
        d = a - xb @ a_inv @ xb
        s11 = np.linalg.solve(d, xb @ a_inv @ (x[:, :, None] * a) - b)
        s12 = np.linalg.solve(d, x[:, :, None] * (a - b @ a_inv @ b))
        return s11, s12, s12, s11

    def region(self, eps: np.ndarray, side: str):
        """Scattering matrix of the semi-infinite medium above (``ref``) or below (``trn``)."""
        ratio = self._v_uniform(_kz(eps[:, None] - self.kx**2), eps) / self.v_gap
        a, b = 1.0 + ratio, 1.0 - ratio
        eye = np.eye(self.n)
        diag = lambda v: v[:, :, None] * eye  # noqa: E731
        if side == "ref":
            return diag(-b / a), diag(2.0 / a), diag(0.5 * (a - b * b / a)), diag(b / a)
        return diag(b / a), diag(0.5 * (a - b * b / a)), diag(2.0 / a), diag(-b / a)


def star(sa, sb):
    """Redheffer star product ``S_A ⊗ S_B`` of scattering matrices ``(S11, S12, S21, S22)``."""
    a11, a12, a21, a22 = sa
    b11, b12, b21, b22 = sb
    eye = np.eye(a11.shape[-1])
    d = a12 @ np.linalg.inv(eye - b11 @ a22)
    f = b21 @ np.linalg.inv(eye - a22 @ b11)
    return (a11 + d @ b11 @ a21, d @ b12, f @ a21, b22 + f @ a22 @ b12)


def _power(s, count: int):
    """``S ⊗ S ⊗ … ⊗ S`` (``count`` ≥ 1 times) by repeated squaring."""
    result = None
    while count:
        if count & 1:
            result = s if result is None else star(result, s)
        count >>= 1
        if count:
            s = star(s, s)
    return result


def _chain(solver: _Solver, pieces: list[Slice]):
    out = None
    for piece in pieces:
        s = solver.slab(piece)
        out = s if out is None else star(out, s)
    return out


def lattice_reflectance(
    lattice: RodLattice,
    wavelength_nm: np.ndarray,
    *,
    n_rod: np.ndarray | complex,
    n_matrix: np.ndarray | complex,
    n_above: np.ndarray | complex | None = None,
    incidence_rad: float = 0.0,
    polarisation: str = "unpolarised",
    harmonics: int = 12,
    per_diameter: int = 16,
) -> np.ndarray:
    """Specular (zeroth-order) reflectance of the rod lattice, per wavelength.

    ``n_above`` is the medium light comes from (default: the matrix, as if the stack were embedded);
    the cortex (``lattice.cortex``, matrix material) lies between it and the rods, the matrix fills
    everything below. ``polarisation``: ``"TE"`` (E along the rods), ``"TM"`` or ``"unpolarised"``.
    Air channels have index 1. Indices may be arrays over wavelength (dispersion).
    """
    lam = np.atleast_1d(np.asarray(wavelength_nm, dtype=np.float64))
    if polarisation == "unpolarised":
        kwargs = dict(
            n_rod=n_rod,
            n_matrix=n_matrix,
            n_above=n_above,
            incidence_rad=incidence_rad,
            harmonics=harmonics,
            per_diameter=per_diameter,
        )
        te = lattice_reflectance(lattice, lam, polarisation="TE", **kwargs)
        tm = lattice_reflectance(lattice, lam, polarisation="TM", **kwargs)
        return 0.5 * (te + tm)
    if polarisation not in ("TE", "TM"):
        raise ValueError(f"polarisation must be 'TE', 'TM' or 'unpolarised', got {polarisation!r}")

    def eps_of(n):
        return np.broadcast_to(np.asarray(n, dtype=np.complex128) ** 2, lam.shape).copy()

    eps = {"matrix": eps_of(n_matrix), ROD: eps_of(n_rod), "air": np.ones_like(lam, complex)}
    eps_above = eps["matrix"] if n_above is None else eps_of(n_above)
    kx0 = np.sqrt(eps_above).real * np.sin(incidence_rad) * np.ones_like(lam)
    solver = _Solver(lattice.check(), lam, eps, eps["matrix"], kx0, harmonics, polarisation)

    total = solver.region(eps_above, "ref")
    if lattice.cortex > 0.0:
        total = star(total, solver.uniform_slab(eps["matrix"], lattice.cortex))
    cells = lattice.cells(per_diameter)
    total = star(total, _chain(solver, cells.top))
    if cells.n_bulk:
        first = _chain(solver, cells.bulk[0])
        if lattice.shift:
            pair = star(first, _chain(solver, cells.bulk[1]))
            if cells.n_bulk >= 2:
                total = star(total, _power(pair, cells.n_bulk // 2))
            if cells.n_bulk % 2:
                total = star(total, first)
        else:
            total = star(total, _power(first, cells.n_bulk))
    if cells.bottom:
        total = star(total, _chain(solver, cells.bottom))
    total = star(total, solver.region(eps["matrix"], "trn"))

    r = total[0][:, :, solver.n // 2]  # incident: the zeroth harmonic, unit amplitude
    kz_ref = _kz(eps_above[:, None] - solver.kx**2)
    if polarisation == "TE":
        weight = kz_ref.real / kz_ref[:, solver.n // 2].real[:, None]
    else:
        ratio = kz_ref / eps_above[:, None]
        weight = ratio.real / ratio[:, solver.n // 2].real[:, None]
    return np.sum(np.abs(r) ** 2 * weight, axis=-1)


def grcwa_reflectance(
    lattice: RodLattice,
    wavelength_nm: float,
    *,
    n_rod: complex,
    n_matrix: complex,
    incidence_rad: float = 0.0,
    harmonics: int = 21,
    per_diameter: int = 10,
    grid: int = 512,
) -> float:
    """Unpolarised reflectance of the same lattice (embedded in the matrix) by ``grcwa``.

    An independent implementation (Jin et al. 2020, ACS Photonics 7:2350) used by tests and
    ``pavonine figures`` to cross-check :func:`lattice_reflectance`: every slab is rasterised on
    ``grid`` points and solved as a 2-D grating with a short second period (only the ``x`` orders
    survive the circular truncation). Raises ``ImportError`` when grcwa is not installed.
    """
    import grcwa

    grcwa.set_backend("numpy")
    period = lattice.check().period
    x = (np.arange(grid) + 0.5) / grid * period
    eps_of = {ROD: complex(n_rod) ** 2, "air": 1.0 + 0j}
    eps_matrix = complex(n_matrix) ** 2
    pieces = lattice.slices_between(lattice.cortex, lattice.depth, per_diameter)
    out = []
    for p_amp, s_amp in ((1.0, 0.0), (0.0, 1.0)):
        obj = grcwa.obj(
            harmonics,
            [period, 0.0],
            [0.0, 0.05 * period],
            1.0 / wavelength_nm,
            incidence_rad,
            0.0,
            verbose=0,
        )
        obj.Add_LayerUniform(0.0, eps_matrix)
        if lattice.cortex > 0.0:
            obj.Add_LayerUniform(lattice.cortex, eps_matrix)
        grids = []
        for piece in pieces:
            eps = np.full(grid, eps_matrix)
            for s in piece.segments:
                dx = (x - s.centre + 0.5 * period) % period - 0.5 * period
                eps[np.abs(dx) < s.half_width] = eps_of[s.kind]
            obj.Add_LayerGrid(piece.thickness, grid, 1)
            grids.append(eps)
        obj.Add_LayerUniform(0.0, eps_matrix)
        obj.Init_Setup()
        obj.GridLayer_geteps(np.concatenate(grids))
        obj.MakeExcitationPlanewave(p_amp, 0.0, s_amp, 0.0, order=0)
        reflected, _ = obj.RT_Solve(normalize=1)
        out.append(float(np.real(reflected)))
    return 0.5 * (out[0] + out[1])
