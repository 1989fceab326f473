"""Native output kept off the command's streams (pavonine/native_output.py)."""

import contextlib
import os
import threading


def test_descriptors_moved_on_threads_come_back():
    """Threads that each silence or capture descriptor 2 at once leave it where it was: without
    the lock one thread restored the other's /dev/null and a command's error line vanished."""
    from pavonine.native_output import captured, silenced

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
