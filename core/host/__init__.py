"""The host: the registry of problems and solvers (`handeye.host.registry`, pluggy) and the door
every solve goes through (`handeye.host.api`: options parsed, capabilities checked, the answer
checked by `handeye.checks.self_check`). It sits above the contracts (`handeye.framework`) and the
checks, below every plugin and command that solves."""
