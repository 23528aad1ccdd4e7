"""The framework: the contracts a plugin fulfils and the host that runs it.

`problem` (the Problem contract), `solver` (SolverSpec), `options`, `solution` (SolverOutput,
Solution, Status), `errors`, `hookspecs` and `registry` (plugins found through entry points and
pluggy), and the host: `api` (`solve`, `run_registered`: the one door to a solver, its checks
before and the self-check after), `isolation` (a solver in a worker process under a time limit)
`processes` (worker processes that end with their parent) and `threads` (one BLAS thread while
solving); `caching` (functools.cached_property without Python 3.11's lock). Depends on the layers
below it (checks, estimation, geometry), never on a built-in problem or plugin.
"""
