"""Keep freed memory in the process heap while a command runs (glibc only).

The dense stability charts step thousands of batches of numpy temporaries of 0.1-4 MiB
(``milling.sdm._monodromy`` and ``_linalg.batched_expm``). glibc gives the top of the heap
back to the kernel whenever more than twice the last large block is free there, so the next
batch faults every page in again (and blocks above the mapping threshold, 128 KiB until one
is freed, get a fresh mapping each time): ``mill lobes --x 2400 --y 0 --rz 45 --samples 100`` took
8.8 million minor page faults and 16.7 s of system CPU beside 26 s of user CPU (thread
limits changed nothing). Blocks up to 32 MiB from the heap and up to 128 MiB of free heap
kept (``M_MMAP_THRESHOLD``, ``M_TRIM_THRESHOLD``) take the system CPU to 0.1 s with the same
peak memory; only the command-line process is tuned, never a program that imports robovib.
"""

from __future__ import annotations

import ctypes
import sys

#: ``mallopt`` parameters of glibc.
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
#: Blocks up to this size come from the heap, not from their own mapping [bytes] (glibc's
#: largest; its default is 128 KiB, raised only as blocks are freed).
MMAP_THRESHOLD_BYTES = 32 * 2**20
#: Free memory at the top of the heap kept before any is given back [bytes].
TRIM_THRESHOLD_BYTES = 128 * 2**20


def keep_freed_heap(
    mmap_threshold_bytes: int = MMAP_THRESHOLD_BYTES,
    trim_threshold_bytes: int = TRIM_THRESHOLD_BYTES,
) -> bool:
    """Ask glibc's allocator to serve blocks from the heap and keep freed heap for reuse.

    Parameters
    ----------
    mmap_threshold_bytes : int
        Blocks up to this size come from the heap [bytes] (``mallopt(M_MMAP_THRESHOLD)``).
    trim_threshold_bytes : int
        Free memory at the top of the heap kept before any is given back to the kernel
        [bytes] (``mallopt(M_TRIM_THRESHOLD)``).

    Returns
    -------
    bool
        Whether both settings took (``False`` off Linux, or where ``mallopt`` is missing or a
        stub, as in musl).
    """
    if not sys.platform.startswith("linux"):
        return False
    try:  # the C library the interpreter runs on (no ldconfig subprocess to find it)
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # no mallopt to call
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    took = mallopt(_M_MMAP_THRESHOLD, int(mmap_threshold_bytes)) == 1
    return mallopt(_M_TRIM_THRESHOLD, int(trim_threshold_bytes)) == 1 and took
