"""``handeye list``: the registered problems and solvers, with backends, availability,
providing distribution and citation, and the plugins that failed to load (``--json`` for
machines)."""

from __future__ import annotations

import argparse
import dataclasses
from typing import Any

from handeye.cli._common import dump_json
from handeye.host.registry import get_registry

NAME = "list"


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        NAME, help="list problems and solvers", description=__doc__.split("\n\n")[0],
    )
    parser.add_argument("--problem", help="only solvers of this problem")
    output = parser.add_mutually_exclusive_group()
    output.add_argument("--json", action="store_true", help="machine-readable output")
    output.add_argument("--markdown", action="store_true", help="the solver table as Markdown (for README.md)")
    parser.set_defaults(run=run)
    return parser


def collect(problem: str | None = None) -> dict[str, Any]:
    """The listing as a JSON-ready dict: {"problems": [...], "solvers": [...], "failed_plugins":
    [{"name", "distribution", "version", "error"}, ...]}."""
    registry = get_registry()
    problems = [
        {"name": p.name, "summary": p.summary, "data": list(p.data_fields), "unknowns": list(p.unknowns)}
        for name, p in sorted(registry.problems.items())
    ]
    solvers = []
    for name in registry.solver_names(problem):
        served = [problem] if problem is not None else registry.solver_problems(name)
        specs = {p: registry.solver(name, p) for p in served}
        first = specs[served[0]]
        provider = registry.provider(name, served[0])
        per_problem = []
        for p, spec in specs.items():
            backends = []
            for backend in spec.backends:
                reason = spec.unavailable_reason(backend)
                backends.append({"name": backend, "default": backend == spec.default_backend,
                                 "available": reason is None, "reason": reason})
            info = registry.provider(name, p)
            per_problem.append({"problem": p, "summary": spec.summary, "backends": backends,
                                "options": spec.option_names(), "citation": spec.citation,
                                "plugin": info.name, "distribution": info.distribution, "version": info.version})
        solvers.append({
            "name": name, "problems": served, "summary": first.summary,
            "backends": per_problem[0]["backends"], "options": first.option_names(), "citation": first.citation,
            "plugin": provider.name, "distribution": provider.distribution, "version": provider.version,
            "per_problem": per_problem,
        })
    failed = [dataclasses.asdict(f) for _, f in sorted(registry.failed.items())]
    return {"problems": problems, "solvers": solvers, "failed_plugins": failed}


def markdown_table(listing: dict[str, Any]) -> str:
    """The solvers as a Markdown table: name, problems, backends (default first), citation. A
    solver whose backends or citation differ between its problems says so per problem."""
    rows = ["| solver | problems | backends (default first) | citation |", "|---|---|---|---|"]
    for s in listing["solvers"]:
        rows.append(f"| `{s['name']}` | {', '.join(s['problems'])} | {_per_problem(s, _backend_list)} | "
                    f"{_per_problem(s, lambda p: p['citation']).replace('|', '/')} |")
    return "\n".join(rows)


def _backend_list(entry: dict[str, Any]) -> str:
    return ", ".join(b["name"] for b in sorted(entry["backends"], key=lambda b: not b["default"]))


def _per_problem(solver: dict[str, Any], field: Any) -> str:
    """field(entry) when it is the same for every problem of the solver, else each with its problem."""
    values = [(p["problem"], field(p)) for p in solver["per_problem"]]
    if len({v for _, v in values}) == 1:
        return values[0][1]
    return "; ".join(f"{problem}: {value}" for problem, value in values)


def run(args: argparse.Namespace) -> int:
    listing = collect(args.problem)
    if args.json:
        print(dump_json(listing))
        return 0
    if args.markdown:
        print(markdown_table(listing))
        return 0
    print("problems:")
    for p in listing["problems"]:
        print(f"  {p['name']:<10} {p['summary']} (data {', '.join(p['data'])}; unknowns {', '.join(p['unknowns'])})")
    print()
    print("solvers (* = default backend):")
    for s in listing["solvers"]:
        print(f"  {s['name']:<16} [{', '.join(s['problems'])}] {s['summary']}")
        for entry in s["per_problem"]:
            if len(s["per_problem"]) > 1:
                print(f"    {entry['problem']}:" + (f" {entry['summary']}" if entry["summary"] != s["summary"] else ""))
            for b in entry["backends"]:
                mark = "*" if b["default"] else " "
                state = "available" if b["available"] else f"UNAVAILABLE: {b['reason']}"
                print(f"      backend {b['name'] + mark:<10} {state}")
            if entry["options"]:
                print(f"      options  {', '.join(entry['options'])}")
            version = f" {entry['version']}" if entry["version"] else ""
            print(f"      from     {entry['distribution']}{version} (plugin {entry['plugin']})")
            if entry["citation"]:
                print(f"      cite     {entry['citation']}")
    if listing["failed_plugins"]:
        print()
        print("plugins that failed to load (skipped):")
        for f in listing["failed_plugins"]:
            print(f"  {f['name']:<16} from {f['distribution']} {f['version']}: {f['error']}")
    return 0
