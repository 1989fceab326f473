"""A real Dask cluster on 127.0.0.1: ``dask scheduler`` and two ``dask worker`` processes.

Renders a 4-frame turntable through ``--scheduler`` and checks the frames against renders made
in this process; kills a worker mid-run and checks that the job still completes with correct,
complete frames; merges a frame split by samples and passes ``compare --method stat`` against a
single-process render of the same total samples; converts two recipes on the cluster; reports
bad input found on a worker in one line. Every
process started here is killed (its whole process group) when the test ends, pass or fail.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("distributed")

from pavonine.render.imageio import read_exr

pytestmark = [pytest.mark.farm, pytest.mark.render]
REPO = Path(__file__).parents[2]
EYE = REPO / "assets" / "scenes" / "eye_feather_sun.usda"
TURNTABLE = ["--turntable", "4", "--spp", "8", "--resolution", "32x48", "-q"]
STARTUP_TIMEOUT_S = 90


class LocalDask:
    """A scheduler and workers as separate OS processes (each in its own process group)."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.file = folder / "scheduler.json"
        self.procs: dict[str, subprocess.Popen] = {}
        env = {**os.environ, "PAVONINE_RENDER_THREADS": "1", "PYTHONUNBUFFERED": "1"}
        self.env = env
        self._start(
            "scheduler",
            ["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard"],
            ["--scheduler-file", str(self.file)],
        )
        deadline = time.monotonic() + STARTUP_TIMEOUT_S
        while not self.file.exists():
            self._alive("scheduler")
            if time.monotonic() > deadline:
                raise TimeoutError("dask scheduler did not start")
            time.sleep(0.1)
        time.sleep(0.2)  # the file is written before it is complete on slow machines
        self.address = json.loads(self.file.read_text())["address"]

    def _start(self, name: str, command: list[str], extra: list[str]) -> None:
        log = open(self.folder / f"{name}.log", "w")
        self.procs[name] = subprocess.Popen(
            [sys.executable, "-m", "dask", *command, *extra],
            stdout=log,
            stderr=subprocess.STDOUT,
            env=self.env,
            start_new_session=True,
        )

    def _alive(self, name: str) -> None:
        if self.procs[name].poll() is not None:
            log = (self.folder / f"{name}.log").read_text()[-2000:]
            raise RuntimeError(f"{name} exited early:\n{log}")

    def add_workers(self, count: int) -> None:
        from distributed import Client

        for _i in range(count):
            name = f"w{len(self.procs) - 1}"
            self._start(
                name,
                ["worker", "--nthreads", "1", "--no-nanny", "--no-dashboard"],
                ["--host", "127.0.0.1", "--name", name, "--scheduler-file", str(self.file)],
            )
        with Client(self.address, timeout=30) as client:
            client.wait_for_workers(len(self.procs) - 1, timeout=STARTUP_TIMEOUT_S)

    def kill(self, name: str) -> None:
        proc = self.procs[name]
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=30)

    def close(self) -> None:
        for name in reversed(list(self.procs)):
            try:
                self.kill(name)
            except (ProcessLookupError, subprocess.TimeoutExpired):
                pass


@pytest.fixture(scope="module")
def shared_dask(tmp_path_factory):
    """A scheduler and two workers shared by the tests that do not kill any."""
    cluster = LocalDask(tmp_path_factory.mktemp("dask"))
    try:
        cluster.add_workers(2)
        yield cluster
    finally:
        cluster.close()


@pytest.fixture
def local_dask(tmp_path):
    """A scheduler and two workers of this test alone (it may kill them)."""
    cluster = LocalDask(tmp_path)
    try:
        cluster.add_workers(2)
        yield cluster
    finally:
        cluster.close()


def pavonine(*args: str, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "pavonine.apps.cli", *args],
        capture_output=True,
        text=True,
        timeout=600,
        **kwargs,
    )


def stat_compare(folder: Path, test: str, ref: str) -> subprocess.CompletedProcess:
    """``pavonine compare --method stat`` of ``folder/test.exr`` against ``folder/ref.exr``, each
    with the variance image the render wrote beside it."""
    return pavonine(
        "compare",
        str(folder / f"{test}.exr"),
        str(folder / f"{ref}.exr"),
        "--test-variance",
        str(folder / f"{test}.variance.exr"),
        "--ref-variance",
        str(folder / f"{ref}.variance.exr"),
        "--method",
        "stat",
        "-o",
        str(folder / f"heat-{test}"),
    )


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> list[np.ndarray]:
    """The turntable rendered without a cluster (the frames a cluster must reproduce)."""
    tmp_path = tmp_path_factory.mktemp("reference")
    done = pavonine(
        "render", str(EYE), "-o", str(tmp_path / "ref" / "eye.exr"), *TURNTABLE, "--workers", "0"
    )
    assert done.returncode == 0, done.stderr
    return [read_exr(tmp_path / "ref" / f"eye.000{i}.exr")[0] for i in range(4)]


def check_frames(folder: Path, reference: list[np.ndarray]) -> list[dict]:
    """Four complete frames equal to the reference (same seeds; up to float summation order)."""
    assert sorted(p.name for p in folder.glob("eye.*.exr")) == [f"eye.000{i}.exr" for i in range(4)]
    assert not list(folder.glob(".*")), "a temporary file was left behind"
    headers = []
    for i, ref in enumerate(reference):
        pixels, attrs = read_exr(folder / f"eye.000{i}.exr")
        assert pixels.shape == ref.shape == (48, 32, 3)
        assert np.all(np.isfinite(pixels)) and pixels.max() > 0
        assert np.abs(pixels - ref).max() <= 1e-4 * max(float(ref.max()), 1.0), i
        assert attrs["pavonine:camera"] == f"/Turntable/Camera_000{i}"
        headers.append(attrs)
    assert not np.allclose(reference[0], reference[1])  # the camera did turn
    return headers


def test_turntable_through_an_existing_scheduler(shared_dask, reference, tmp_path):
    out = tmp_path / "farm"
    done = pavonine(
        "render",
        str(EYE),
        "-o",
        str(out / "eye.exr"),
        *TURNTABLE,
        "--scheduler",
        shared_dask.address,
    )
    assert done.returncode == 0, done.stderr
    assert "4 image(s), 4 task(s) on 2 worker(s)" in done.stdout
    headers = check_frames(out, reference)
    workers = {json.loads(h["pavonine:workers"])[0].split(" ")[0] for h in headers}
    assert len(workers) == 2  # both workers rendered


def test_a_worker_killed_mid_run_has_its_task_rescheduled(local_dask, reference, tmp_path):
    from distributed import Client

    out = tmp_path / "farm"
    command = [
        sys.executable,
        "-m",
        "pavonine.apps.cli",
        "render",
        str(EYE),
        "-o",
        str(out / "eye.exr"),
    ]
    job = subprocess.Popen(
        [*command, *TURNTABLE, "--scheduler", local_dask.address],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        victim = None
        with Client(local_dask.address, timeout=30) as client:
            deadline = time.monotonic() + 120
            while victim is None and time.monotonic() < deadline:
                busy = {a: keys for a, keys in client.processing().items() if keys}
                names = {a: w["name"] for a, w in client.scheduler_info()["workers"].items()}
                # The two snapshots are taken apart: a worker may be busy in one and not yet
                # (or no longer) listed in the other; look again then.
                busy = {a: keys for a, keys in busy.items() if a in names}
                if busy:
                    victim_address = sorted(busy)[0]
                    victim, killed_tasks = names[victim_address], busy[victim_address]
                    local_dask.kill(victim)
                time.sleep(0.05)
        assert victim is not None, "no worker ever got a task"
        _stdout, stderr = job.communicate(timeout=600)
    finally:
        if job.poll() is None:
            os.killpg(job.pid, signal.SIGKILL)
    assert job.returncode == 0, stderr
    headers = check_frames(out, reference)
    # every frame whose task was running on the killed worker was rendered again by the other
    assert killed_tasks
    for key in killed_tasks:
        frame = int(str(key).rsplit("-", 2)[-2])
        (worker,) = json.loads(headers[frame]["pavonine:workers"])
        assert not worker.startswith(f"{victim_address} "), (frame, worker)


def test_a_frame_split_by_samples_passes_stat_against_one_render(shared_dask, tmp_path):
    common = ["--spp", "64", "--resolution", "32x48", "--variance", "-q"]
    split = pavonine(
        "render",
        str(EYE),
        "-o",
        str(tmp_path / "split.exr"),
        *common,
        "--split",
        "4",
        "--scheduler",
        shared_dask.address,
    )
    assert split.returncode == 0, split.stderr
    attrs = read_exr(tmp_path / "split.exr")[1]
    assert attrs["pavonine:shards"] == 4 and attrs["pavonine:spp"] == 64
    single = pavonine(
        "render",
        str(EYE),
        "-o",
        str(tmp_path / "one.exr"),
        *common,
        "--workers",
        "0",
        "--seed",
        "9",
    )
    assert single.returncode == 0, single.stderr

    agree = stat_compare(tmp_path, "split", "one")
    assert agree.returncode == 0, agree.stdout + agree.stderr
    # the test can fail: the same frame with 2 % brighter pixels is told apart
    pixels, _header = read_exr(tmp_path / "one.exr")
    from pavonine.render.imageio import write_exr

    write_exr(tmp_path / "brighter.exr", pixels * 1.02)
    write_exr(
        tmp_path / "brighter.variance.exr", read_exr(tmp_path / "one.variance.exr")[0] * 1.02**2
    )
    assert stat_compare(tmp_path, "split", "brighter").returncode == 1


def test_convert_on_the_cluster(shared_dask, tmp_path):
    maps = tmp_path / "m"
    made = pavonine("maps", "blue", "-o", str(maps), "--size", "48", "--no-contact-sheet")
    assert made.returncode == 0, made.stderr
    geometry = (
        "[geometry]\nlength_cm = 4.0\nrachis_radius_cm = 0.03\nrachis_tip_radius_cm = 0.01\n"
        "bend_cm = 0.3\ncup_cm = 0.2\ncalamus_cm = 0.5\ndisplacement_cm = 0.01\n"
        "base_triangles = 300\n[geometry.lod]\nhigh = 1200\nmedium = 600\nlow = 300\n"
    )
    names = ["blue_a", "blue_b"]
    for name in names:
        body = "".join(
            f'{m} = "m/{m}.png"\n'
            for m in ("alpha", "ocellar", "gradation", "angle", "displacement", "melanin")
        )
        (tmp_path / f"{name}.toml").write_text(
            f'name = "{name}"\n[maps]\n{body}[material]\npreset = "blue"\n{geometry}'
        )
    recipes = [str(tmp_path / f"{n}.toml") for n in names]
    done = pavonine(
        "convert", *recipes, "-o", str(tmp_path / "out"), "--scheduler", shared_dask.address
    )
    assert done.returncode == 0, done.stdout + done.stderr
    roots = [tmp_path / "out" / n / f"{n}.usd" for n in names]
    assert all(r.is_file() for r in roots)
    assert pavonine("validate", *map(str, roots)).returncode == 0
    # a map changed after hashing on the client would be refused by the worker; a recipe whose
    # map is missing is bad input named in the summary, and the other still converts
    (maps / "melanin.png").rename(maps / "gone.png")
    again = pavonine(
        "convert", *recipes, "-o", str(tmp_path / "out2"), "--scheduler", shared_dask.address
    )
    assert again.returncode == 2 and "maps.melanin: no such file" in again.stderr


def test_bad_input_found_on_a_worker_is_one_line(tmp_path):
    """The worker's own "Compute Failed" log of an input error (with its traceback) is dropped:
    the client prints the error, once, in one line."""
    scene = tmp_path / "scene.usda"
    nan = "float pavonine:crescentSigma = nan\n"
    for name in ("Feather", "Materials", "Feather", "World"):
        nan = f'over "{name}" {{\n{nan}}}\n'
    scene.write_text(f"#usda 1.0\n(\n    subLayers = [@{EYE}@]\n)\n\n{nan}")
    with contextlib.ExitStack() as held:
        # the dashboard's usual port taken (as by a notebook's cluster): no warning about it
        with contextlib.suppress(OSError):  # taken already: as good
            held.enter_context(socket.create_server(("127.0.0.1", 8787)))
        done = pavonine(
            "render", str(scene), "-o", str(tmp_path / "o.exr"), "--frames", "1-2",
            "--workers", "1", "--resolution", "16x12", "--spp", "1",
        )  # fmt: skip
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), done.stderr
    assert "Feather.pavonine:crescentSigma: is NaN" in lines[0]
    assert [p.name for p in tmp_path.iterdir()] == ["scene.usda"]


def test_workers_keep_usd_warnings_off_the_terminal(tmp_path):
    """A missing reference is said once, by the client, not again as USD's raw lines from each
    worker of an embedded cluster."""
    scene = tmp_path / "scene.usda"
    scene.write_text(
        f"#usda 1.0\n(\n    subLayers = [@{EYE}@]\n)\n"
        'def Xform "A" (\n    prepend references = @./nope.usda@\n)\n{\n}\n'
    )
    done = pavonine(
        "render", str(scene), "-o", str(tmp_path / "o.exr"), "--frames", "1-2",
        "--workers", "1", "--resolution", "16x12", "--spp", "1", "-q",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "Warning: in " not in done.stderr, done.stderr
    assert (tmp_path / "o.0001.exr").is_file() and (tmp_path / "o.0002.exr").is_file()


def test_glints_are_the_same_in_one_process_on_workers_and_split_by_samples(shared_dask, tmp_path):
    """Glitter's blocks hash integers, never a sample: the sunlit close-up rendered in this
    process, on the cluster as one task, and split by samples over 2 and 4 tasks passes
    ``compare --method stat`` against the single-process render; the same frame with another
    seed of the blocks is told apart."""
    from glint_scene import closeup_stage

    scene = closeup_stage(tmp_path / "glints.usda", 1.0, resolution=48)
    reseeded = closeup_stage(tmp_path / "reseeded.usda", 1.0, resolution=48, glitter_seed=5)
    common = ["--spp", "64", "--variance", "-q"]
    runs = {
        "one": (scene, ["--workers", "0", "--seed", "9"]),
        "cluster": (scene, ["--scheduler", shared_dask.address, "--seed", "3"]),
        "split2": (scene, ["--split", "2", "--scheduler", shared_dask.address]),
        "split4": (scene, ["--split", "4", "--scheduler", shared_dask.address]),
        "reseeded": (reseeded, ["--workers", "0", "--seed", "9"]),
    }
    for name, (stage, extra) in runs.items():
        done = pavonine("render", str(stage), "-o", str(tmp_path / f"{name}.exr"), *common, *extra)
        assert done.returncode == 0, (name, done.stderr)

    for name in ("cluster", "split2", "split4"):
        agree = stat_compare(tmp_path, name, "one")
        assert agree.returncode == 0, (name, agree.stdout + agree.stderr)
    assert stat_compare(tmp_path, "reseeded", "one").returncode == 1


def test_blurred_frames_on_workers_sync_only_what_varies_and_equal_fresh_renders(
    shared_dask, tmp_path
):
    """Frames of a moving quad with its shutter open, on two workers: each worker syncs the stage
    once and moves only the quad to its later frames (their sync is a fraction of the first's),
    and every frame is the fresh single-time render of that time, bit for bit."""
    from motion_scene import motion_stage

    stage = tmp_path / "moving.usda"
    motion_stage(stage, (-0.25, 0.25))
    common = ["--spp", "16", "--seed", "4", "-q"]
    farm = pavonine(
        "render", str(stage), "-o", str(tmp_path / "f.exr"), "--frames", "0-3", *common,
        "--scheduler", shared_dask.address, "--json", str(tmp_path / "farm.json"),
    )  # fmt: skip
    assert farm.returncode == 0, farm.stderr
    report = json.loads((tmp_path / "farm.json").read_text())
    assert {len(image["warnings"]) for image in report["images"]} == {0}
    for frame in range(4):
        fresh = pavonine(
            "render", str(stage), "-o", str(tmp_path / f"one.{frame}.exr"), "--time",
            str(frame), *common,
        )  # fmt: skip
        assert fresh.returncode == 0, fresh.stderr
        farmed = read_exr(tmp_path / f"f.{frame:04d}.exr")[0]
        assert np.array_equal(farmed, read_exr(tmp_path / f"one.{frame}.exr")[0]), frame
    syncs: dict[str, list[float]] = {}
    for task in report["tasks"]:
        syncs.setdefault(task["worker"], []).append(task["seconds"]["sync"])
    assert any(len(times) > 1 for times in syncs.values()), "no worker rendered two frames"
    for times in syncs.values():  # one full sync per worker, the others only the quad's
        first, *later = sorted(times, reverse=True)
        assert all(t < first / 2 for t in later), times
