"""Where a render's resident memory goes: RSS at the end of each phase and its peak within it.

Renders one stage once in this process (run it fresh: ``python benchmarks/rss_phases.py SCENE``)
while a thread samples ``VmRSS`` from ``/proc/self/status`` every 10 ms. The phases are marked by
wrapping Pavonine's own steps: opening the USD stage, the delegate's sync (USD to Mitsuba dicts),
``mitsuba.load_dict`` (the Mitsuba scene and integrator), each ``mi.render`` pass, and the rest
(film to numpy, the result). tracemalloc cannot see this memory (most of it is native: USD,
Mitsuba, Dr.Jit, LLVM), hence RSS.

Usage: python benchmarks/rss_phases.py SCENE [--resolution 1024x768] [--spp 64] [--seed 0]
"""

from __future__ import annotations

import argparse
import functools
import threading
import time
import warnings

_state = {"phase": "start-up (imports)", "peak": 0, "rows": []}


def rss_kib() -> int:
    """This process's resident set, KiB (``VmRSS``)."""
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return 0


def mark(phase: str) -> None:
    """End the current phase (its RSS now and its peak) and start ``phase``."""
    now = rss_kib()
    _state["rows"].append((_state["phase"], now, max(_state["peak"], now)))
    _state["phase"], _state["peak"] = phase, now


def _sample(stop: threading.Event) -> None:
    while not stop.wait(0.01):
        _state["peak"] = max(_state["peak"], rss_kib())


def _wrapped(owner, name: str, before: str, after: str) -> None:
    """Mark ``before`` on entering ``owner.name`` and ``after`` on leaving it."""
    inner = getattr(owner, name)

    @functools.wraps(inner)
    def wrapper(*args, **kwargs):
        mark(before)
        try:
            return inner(*args, **kwargs)
        finally:
            mark(after)

    setattr(owner, name, wrapper)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--resolution", default="1024x768")
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    stop = threading.Event()
    threading.Thread(target=_sample, args=(stop,), daemon=True).start()
    import mitsuba

    from pavonine.render import api, passes
    from pavonine.render.diagnostics import StageWarning

    mark("between (api start)")
    _wrapped(api, "open_stage", "USD open", "between (settings, delegate)")
    _wrapped(api.StageDelegate, "sync", "sync (USD -> dicts)", "between (scene dict)")
    _wrapped(mitsuba, "load_dict", "mitsuba.load_dict", "between (after load_dict)")
    _wrapped(passes, "render_pass", "render pass", "between passes / after")
    width, height = (int(v) for v in args.resolution.split("x"))
    started = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        api.render_stage(
            args.scene, spp=args.spp, resolution=(width, height), seed=args.seed, progress=False
        )
    mark("end")
    stop.set()
    print(f"{args.scene} {args.resolution} @ {args.spp} spp: {time.perf_counter() - started:.1f} s")
    print(f"{'phase':<34} {'RSS at end':>11} {'peak in it':>11}  (MiB)")
    for phase, now, peak in _state["rows"]:
        print(f"{phase:<34} {now / 1024:11.0f} {peak / 1024:11.0f}")
    with open("/proc/self/status") as status:
        hwm = next(line for line in status if line.startswith("VmHWM:"))
    print(f"VmHWM {int(hwm.split()[1]) / 1024:.0f} MiB")


if __name__ == "__main__":
    main()
