"""Native output kept off the command's streams (base/native_output.py)."""

import contextlib
import os
import threading


def test_descriptors_moved_on_threads_come_back():
    """Threads that each silence or capture descriptor 2 at once leave it where it was: without
    the lock one thread restored the other's /dev/null and a command's error line vanished."""
    from pavonine.base.native_output import captured, silenced

    before = os.fstat(2)
    barrier = threading.Barrier(4, timeout=10)

    def work(block):
        with contextlib.suppress(threading.BrokenBarrierError):
            barrier.wait(timeout=0.05)
        for _ in range(50):
            with block():
                os.write(2, b"")

    threads = [threading.Thread(target=work, args=(b,)) for b in (silenced, captured) * 2]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    after = os.fstat(2)
    assert (after.st_dev, after.st_ino) == (before.st_dev, before.st_ino)


def test_a_block_on_another_thread_never_waits_for_an_open_one():
    """USD's validators run on worker threads inside validate's silenced block and capture
    libpng's lines there: holding a lock across the outer block deadlocked ``pavonine
    validate``."""
    from pavonine.base.native_output import captured, silenced

    done = threading.Event()

    def inner():
        with captured(2) as lines:
            os.write(2, b"from the worker\n")
        done.set()
        assert lines == ["from the worker"]

    with silenced(2):
        worker = threading.Thread(target=inner)
        worker.start()
        worker.join(timeout=10)
    assert done.is_set(), "a capture on a worker thread waited for the main thread's block"


def test_the_newest_open_block_takes_the_descriptor_and_the_oldest_restores_it():
    """Blocks closing out of order (A opens, B opens, A closes, B closes) leave the descriptor on
    B's target until B closes, then on the original."""
    from pavonine.base import native_output

    before = os.fstat(2)
    a, b = native_output.captured(2), native_output.captured(2)
    lines_a = a.__enter__()
    lines_b = b.__enter__()
    a.__exit__(None, None, None)
    os.write(2, b"for b\n")
    b.__exit__(None, None, None)
    after = os.fstat(2)
    assert lines_b == ["for b"] and lines_a == []
    assert (after.st_dev, after.st_ino) == (before.st_dev, before.st_ino)
