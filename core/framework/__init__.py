"""The contracts: what a plugin fulfils and what it is given, just above the geometry.

`problem` (the Problem contract), `solver` (SolverSpec), `options`, `solution` (SolverOutput,
Solution, Status) and `hookspecs` (the pluggy hooks a plugin implements); the means of running a
solver that the host and the harness share: `isolation` (a solver in a worker process under a
time limit), `processes` (worker processes that end with their parent), `threads` (one BLAS thread
while solving) and `caching` (functools.cached_property without Python 3.11's lock). The errors
are below (`handeye.base.errors`); the registry and the door every solve goes through are above
the checks (`handeye.host`). Depends on `handeye.base` and `handeye.geometry` only.
"""
