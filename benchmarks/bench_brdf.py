"""BRDF evaluations per second for the full feather model, JIT-compiled by Dr.Jit (llvm variant).

Yardstick, measured in the same run: a plain NumPy multiply-add ``a * b + c`` over arrays of the
same length. Also prints the one-off cost of precomputing the cylinder (row-reflectance) table.
Target: ≥ 20 million evaluations per second on 2 cores.

    python benchmarks/bench_brdf.py [--n 4194304] [--repeats 5]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from pavonine.base.backend import select_variant


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1 << 22, help="evaluations per batch")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    backend = select_variant()
    import drjit as dr
    import mitsuba as mi

    from pavonine.materials import rod
    from pavonine.materials.brdf import RowTable
    from pavonine.materials.jit import JitMaterial
    from pavonine.materials.parameters import preset

    params = preset("paper-table1")
    rod.row_reflectance_table.cache_clear()
    t0 = time.perf_counter()
    table = RowTable.build(complex(params.melanin_index / params.medium_index))
    table_seconds = time.perf_counter() - t0

    material = JitMaterial(params)
    n = args.n
    rng = np.random.default_rng(0)

    def inputs():
        def hemisphere():
            v = rng.normal(size=(3, n)).astype(np.float32)
            v /= np.linalg.norm(v, axis=0)
            v[2] = np.abs(v[2])
            return mi.Vector3f(v)

        return (
            hemisphere(),
            hemisphere(),
            mi.Float(rng.uniform(360, 830, n).astype(np.float32)),
            mi.UInt32(rng.integers(0, 6, n).astype(np.uint32)),
            mi.Float(rng.random(n, dtype=np.float32)),
            mi.Float(rng.random(n, dtype=np.float32)),
        )

    def evaluate(wi, wo, lam, cls, grad, share):
        long_stack, short_stack = material.stacks(cls, grad)
        value = material.brdf(wi, wo, lam, long_stack, short_stack, share)
        dr.eval(value)
        dr.sync_thread()
        return value

    data = [inputs() for _ in range(2)]
    for d in data:
        dr.eval(d)
    evaluate(*data[0])  # trace + compile once
    brdf_times = []
    for i in range(args.repeats):
        t0 = time.perf_counter()
        value = evaluate(*data[i % 2])
        brdf_times.append(time.perf_counter() - t0)
    assert np.all(np.isfinite(np.array(value)))

    a, b, c = (rng.random(n, dtype=np.float32) for _ in range(3))
    fma_times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        np.add(np.multiply(a, b), c)
        fma_times.append(time.perf_counter() - t0)

    brdf_rate = n / min(brdf_times)
    fma_rate = n / min(fma_times)
    print(f"variant            {backend.variant} (libLLVM: {backend.libllvm})")
    print(f"threads            {dr.thread_count()}")
    print(f"batch              {n} evaluations (random directions, λ, class, gradation, melanin)")
    print(f"feather BRDF       {brdf_rate / 1e6:8.1f} M evaluations/s (best of {args.repeats})")
    print(f"numpy a*b+c        {fma_rate / 1e6:8.1f} M elements/s (yardstick)")
    print(f"ratio BRDF/yardstick {brdf_rate / fma_rate:6.3f}")
    print(f"target             {'met' if brdf_rate >= 20e6 else 'NOT met'} (>= 20 M/s)")
    print(
        f"cylinder table     {table_seconds * 1e3:8.1f} ms one-off ({table.n_x}×{table.n_cos} grid)"
    )
    assert math.isfinite(brdf_rate)


if __name__ == "__main__":
    main()
