"""Split the suite into the fast tier (the README's test command) and the second tier, from measurements.

    python -m pytest -n auto --durations=0 -p no:cacheprovider > durations.txt   # the whole suite, timed
    python tests/tiers.py durations.txt [fast.txt] [--budget SECONDS]             # writes tests/second_tier.txt

The fast tier must finish, install included, in five minutes on the project's 2-core machine, and
still hold, for every record of `tests/mutations.py`, at least one of the tests that record names
(so that the fast tier can catch every mutation it can). The split is made in three steps:

1. The tests that run other processes (the README's blocks, multi-process and sharded runs in
   subprocesses, the tiny report) go to the second tier, unless a mutation record has no other test.
2. A greedy set cover picks, for the records, the tests with the least measured time per record
   newly covered; these are fast-tier tests whatever their cost.
3. The remaining tests join the fast tier cheapest first while the measured total stays within
   `--budget` test-seconds (summed over workers, as `--durations` reports them); the rest, the
   statistical calibrations and the wide chi-square and hard-case grids mostly, are the second tier.

A test is in the fast tier unless `tests/second_tier.txt` names it (a node id, or a test function's
id without parameters for all of its cases): a new test runs in the fast tier until the split is
made again.
"""

from __future__ import annotations

import argparse
import collections
import importlib.util
import re
import subprocess
import sys
from pathlib import Path

TESTS = Path(__file__).resolve().parent
ROOT = TESTS.parent
SECOND_TIER_FILE = TESTS / "second_tier.txt"
OTHER_PROCESSES = ("test_readme_blocks_run_outside", "tests/estimators/test_multiprocess.py", "in_subprocess",
                   "test_tiny_report")


def measured(durations_text: str) -> collections.Counter:
    """Seconds per node id (setup, call and teardown) from pytest's `--durations=0` report."""
    seconds = collections.Counter()
    for match in re.finditer(r"^([\d.]+)s (?:call|setup|teardown)\s+(\S+)", durations_text, re.M):
        seconds[match.group(2)] += float(match.group(1))
    return seconds


def collected() -> list[str]:
    out = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider"],
                         cwd=ROOT, capture_output=True, text=True, check=True)
    return [line.strip() for line in out.stdout.splitlines() if "::" in line]


def selected(tests, nodes) -> set[str]:
    """The node ids a mutation record's pytest arguments select (files, node ids, "-k EXPR")."""
    from _pytest.mark.expression import Expression

    tests, expression = list(tests), None
    if "-k" in tests:
        at = tests.index("-k")
        expression = Expression.compile(tests[at + 1])
        del tests[at:at + 2]
    chosen = {node for node in nodes for t in tests
              if node == t or node.startswith((t + "[", t + "::", t.rstrip("/") + "/"))}
    if expression is not None:
        chosen = {node for node in chosen if expression.evaluate(lambda word, node=node: word.lower() in node.lower())}
    return chosen


def mutation_records():
    spec = importlib.util.spec_from_file_location("mutations", TESTS / "mutations.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["mutations"] = module
    spec.loader.exec_module(module)
    return module.MUTATIONS


def split(nodes, seconds, records, budget):
    """(fast, second): node-id sets, as the module docstring describes."""
    cost = {node: max(seconds.get(node, 0.0), 0.01) for node in nodes}
    elsewhere = {node for node in nodes if any(part in node for part in OTHER_PROCESSES)}
    needs = {name: tests for name, tests in records.items() if tests}
    fast, open_records = set(), set(needs)
    while open_records:
        counts = collections.Counter(node for name in open_records for node in needs[name])
        usable = {node: c for node, c in counts.items() if node not in elsewhere} or counts
        best = min(usable, key=lambda node: (cost[node] / usable[node], node))
        fast.add(best)
        open_records = {name for name in open_records if best not in needs[name]}
    spent = sum(cost[node] for node in fast)
    for node in sorted(set(nodes) - fast - elsewhere, key=lambda node: (cost[node], node)):
        if spent + cost[node] > budget:
            break
        fast.add(node)
        spent += cost[node]
    return fast, set(nodes) - fast


def compact(second, nodes) -> list[str]:
    """Node ids, with a function's id standing for all of its cases where all of them are listed."""
    cases = collections.defaultdict(set)
    for node in nodes:
        cases[node.split("[")[0]].add(node)
    out = []
    for function, all_cases in sorted(cases.items()):
        mine = all_cases & second
        out += [function] if mine == all_cases else sorted(mine)
    return out


def in_second_tier(nodeid: str, listed: set[str]) -> bool:
    return nodeid in listed or nodeid.split("[")[0] in listed


def read_second_tier() -> set[str]:
    if not SECOND_TIER_FILE.exists():
        return set()
    return {line.strip() for line in SECOND_TIER_FILE.read_text().splitlines()
            if line.strip() and not line.startswith("#")}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("durations", nargs="+",
                        help="pytest --durations=0 output of the whole suite; a later file's times (of the fast "
                             "tier, say) replace an earlier one's for the tests it names")
    parser.add_argument("--budget", type=float, default=650.0,
                        help="test-seconds of the fast tier, as measured in that run (default 650)")
    args = parser.parse_args(argv)
    seconds = {}
    for path in args.durations:
        seconds.update(measured(Path(path).read_text()))
    nodes = collected()
    records = {m.name: selected(m.tests, nodes) for m in mutation_records()}
    empty = sorted(name for name, tests in records.items() if not tests)
    if empty:
        print(f"records that select no test: {', '.join(empty)}", file=sys.stderr)
    fast, second = split(nodes, seconds, records, args.budget)
    lines = compact(second, nodes)
    header = (f"# The second tier (`pytest -m slow`), made by `python tests/tiers.py` from a timed run of the whole\n"
              f"# suite: {len(fast)} tests in the fast tier ({sum(seconds.get(n, 0.0) for n in fast):.0f} test-seconds "
              f"measured), {len(second)} here ({sum(seconds.get(n, 0.0) for n in second):.0f}).\n")
    SECOND_TIER_FILE.write_text(header + "\n".join(lines) + "\n")
    print(f"fast tier: {len(fast)} tests; second tier: {len(second)} tests in {len(lines)} lines -> {SECOND_TIER_FILE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
