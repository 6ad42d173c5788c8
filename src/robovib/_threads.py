"""BLAS thread limits around small-matrix work.

The GP fits and predictions factorise thousands of matrices of 13-500 rows. Multi-threaded
BLAS does not speed these up: the threads spend their time waking up and synchronising, and on a
busy machine (2 cores shared with other processes) each call waits for a core to be free for
every thread, which measured 7-15x slower than one thread (issue 14). NumPy and SciPy also ship
*separate* OpenBLAS builds whose thread pools contend when their calls alternate in a hot loop
(measured 4x slower on 2 cores). One thread per process is both faster and fair to neighbours;
parallelism belongs at a coarser level (one process per task).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

__all__ = ["single_blas_thread"]

_CONTROLLER = None


def _controller():
    # Discovering the loaded BLAS libraries costs ~0.5 ms; do it once. NumPy and SciPy's BLAS are
    # loaded by the modules that use this (they import numpy and scipy.linalg at import time).
    global _CONTROLLER
    if _CONTROLLER is None:
        from threadpoolctl import ThreadpoolController

        _CONTROLLER = ThreadpoolController()
    return _CONTROLLER


@contextlib.contextmanager
def single_blas_thread() -> Iterator[None]:
    """Limit every loaded BLAS library to one thread inside the ``with`` block.

    Re-entrant and cheap (~10 µs); the previous limits are restored on exit.

    Examples
    --------
    >>> import numpy as np
    >>> with single_blas_thread():
    ...     _ = np.linalg.cholesky(np.eye(3))
    """
    with _controller().limit(limits=1, user_api="blas"):
        yield
