"""One BLAS thread while handeye computes: `one_blas_thread`.

handeye's matrices are small (at most a few hundred rows: 6 (nX + nY) unknowns, a 217-square
relaxation) and its long loops are batched 3x3 products, which OpenBLAS does not thread. Above its
threshold OpenBLAS threads a product or a factorisation over every core, and when another job holds
a core its threads wait for each other: measured on this 2-core machine with a second job running,
a kron-lstsq solve of a cell of 24 poses and 708 observations took 1.0 s with OpenBLAS's two
threads against 25 ms with one (the Cholesky solve of a 144-square matrix alone 0.38 s). One thread
is never slower at these sizes, loaded or not; processes (the harness's workers, image
detection) are how handeye uses the cores. threadpoolctl (the scikit-learn maintainers' library)
sets the limit for every BLAS loaded (numpy's and scipy's OpenBLAS here) and restores it on exit;
a controller built once makes that ~13 us a call.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Iterator

from threadpoolctl import ThreadpoolController


@functools.cache
def _controller() -> ThreadpoolController:
    return ThreadpoolController()


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """Run the block with the BLAS libraries limited to one thread (restored after it)."""
    with _controller().limit(limits=1, user_api="blas"):
        yield
