"""Memory a `taskseq` process frees stays with it for its next allocation (glibc's malloc).

Why: by default glibc returns a freed block of more than 32 MiB (and any large
free space at the top of its heap) to the kernel at once, and the next array
of that size is faulted back in page by page, each page zeroed by the kernel.
A fit builds and drops its score tables, oracle answers and padded feature
rows on every cutting-plane iteration, hundreds of MiB each on a large world,
so without this policy large fits spend more time in the kernel than in their
own arithmetic (docs/scaling-benchmark.md times the fold models of a 130-room
world both ways: the same models to the byte, about half the wall time and a
tenth of the system time with the policy). On a virtual machine whose host
backs guest memory only when the guest first touches it, a page given back
costs most.

The policy: no block is served by `mmap` of its own (`M_MMAP_MAX` 0; glibc
still maps memory when the heap cannot grow, so nothing fails for want of
it), and the heap is trimmed only past 2 GiB of free space at its top. A
process then keeps the memory of its peak until it exits, which a pipeline
stage does when its work is done (`taskseq serve` runs on, with a small
peak). Arithmetic is the same bits: where an array lies in memory changes no
sum.

Child processes (loky's workers, the scaling benchmark's timed fit) take the
policy from two environment variables, which glibc reads when a process
starts. A user who sets either of them keeps their own setting. Where the C
library is not glibc (macOS, musl) nothing changes. Workers of a Dask cluster
started outside `taskseq` keep their own malloc settings.
"""

from __future__ import annotations

import ctypes
import os
import sys

M_TRIM_THRESHOLD, M_MMAP_MAX = -1, -4  # mallopt's parameters (malloc.h)
TRIM_THRESHOLD = 2**31 - 1  # bytes of free space at the heap's top before glibc returns it (mallopt takes an int)
ENVIRONMENT = {"MALLOC_MMAP_MAX_": "0", "MALLOC_TRIM_THRESHOLD_": str(TRIM_THRESHOLD)}


def _glibc() -> ctypes.CDLL | None:
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL("libc.so.6")
    except OSError:
        return None
    return libc if hasattr(libc, "gnu_get_libc_version") and hasattr(libc, "mallopt") else None


def keep_freed_memory() -> bool:
    """Set the policy for this process and the processes it starts; True when this process's malloc took it.

    False, and nothing changed, when the C library is not glibc or when either
    environment variable is already set (by the user, or by a parent that
    applied this policy: glibc then read it when this process started).
    """
    if any(name in os.environ for name in ENVIRONMENT):
        return False
    libc = _glibc()
    if libc is None:
        return False
    os.environ.update(ENVIRONMENT)
    return bool(libc.mallopt(M_MMAP_MAX, 0)) and bool(libc.mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD))
