"""``handeye list``: the registered problems and solvers, with backends, availability,
providing distribution and citation, and the plugins that failed to load (``--json`` for
machines)."""

from __future__ import annotations

import argparse
import dataclasses
from typing import Any

from ..registry import get_registry
from ._common import dump_json

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
        spec = registry.solvers[name]
        provider = registry.provider(name)
        backends = []
        for backend in spec.backends:
            reason = spec.unavailable_reason(backend)
            backends.append({"name": backend, "default": backend == spec.default_backend,
                             "available": reason is None, "reason": reason})
        solvers.append({
            "name": name, "problems": list(spec.problems), "summary": spec.summary,
            "backends": backends, "options": spec.option_names(), "citation": spec.citation,
            "plugin": provider.name, "distribution": provider.distribution, "version": provider.version,
        })
    failed = [dataclasses.asdict(f) for _, f in sorted(registry.failed.items())]
    return {"problems": problems, "solvers": solvers, "failed_plugins": failed}


def markdown_table(listing: dict[str, Any]) -> str:
    """The solvers as a Markdown table: name, problems, backends (default first), citation."""
    rows = ["| solver | problems | backends (default first) | citation |", "|---|---|---|---|"]
    for s in listing["solvers"]:
        backends = sorted(s["backends"], key=lambda b: not b["default"])
        rows.append(f"| `{s['name']}` | {', '.join(s['problems'])} | "
                    f"{', '.join(b['name'] for b in backends)} | {s['citation'].replace('|', '/')} |")
    return "\n".join(rows)


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
        for b in s["backends"]:
            mark = "*" if b["default"] else " "
            state = "available" if b["available"] else f"UNAVAILABLE: {b['reason']}"
            print(f"      backend {b['name'] + mark:<10} {state}")
        if s["options"]:
            print(f"      options  {', '.join(s['options'])}")
        version = f" {s['version']}" if s["version"] else ""
        print(f"      from     {s['distribution']}{version} (plugin {s['plugin']})")
        if s["citation"]:
            print(f"      cite     {s['citation']}")
    if listing["failed_plugins"]:
        print()
        print("plugins that failed to load (skipped):")
        for f in listing["failed_plugins"]:
            print(f"  {f['name']:<16} from {f['distribution']} {f['version']}: {f['error']}")
    return 0
