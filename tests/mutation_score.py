"""The mutation score per module, from mutmut's results: `python tests/mutation_score.py` after `mutmut run`.

A mutant counts as caught when a test failed on it or it hung until mutmut stopped it (a timeout: the bug made the
tests loop). Mutants listed in tests/mutation_equivalents.txt, with the reason no input can tell them from the
original, are left out of the score; a listed name mutmut no longer reports (the source moved, so mutmut numbers its
mutants anew) is printed, to be checked again. Prints a Markdown table of the modules whose mutants were run (a
run of some modules, `mutmut run "searchrl.world.obstacles*"`, leaves the others unchecked: they are named, not
scored); exits 1 when a module scores below 90 % or has mutants left unchecked.
"""

from __future__ import annotations

import subprocess
import sys
from collections import Counter, defaultdict
from pathlib import Path

EQUIVALENTS = Path(__file__).with_name("mutation_equivalents.txt")
CAUGHT = {"killed", "timeout"}
FLOOR = 0.90


def results() -> dict[str, str]:
    """mutant name -> status (killed, survived, timeout, no tests, not checked, ...)."""
    out = subprocess.run(["mutmut", "results", "--all", "true"], capture_output=True, text=True, check=True).stdout
    statuses = {}
    for line in out.splitlines():
        name, sep, status = line.strip().rpartition(": ")
        if sep and name.startswith("searchrl."):
            statuses[name] = status
    return statuses


def equivalents() -> set[str]:
    """Names in the first column of mutation_equivalents.txt (comments after '#', blank lines skipped)."""
    lines = (line.split("#", 1)[0].split() for line in EQUIVALENTS.read_text().splitlines())
    return {words[0] for words in lines if words}


def module_of(name: str) -> str:
    """searchrl.evaluate.record.x_claim_folder__mutmut_3 -> searchrl/evaluate/record.py"""
    path = name.split(".x_", 1)[0].split(".xǁ", 1)[0]
    return path.replace(".", "/") + ".py"


def main() -> int:
    statuses, equivalent = results(), equivalents()
    stale = sorted(equivalent - set(statuses))
    counts: dict[str, Counter] = defaultdict(Counter)
    for name, status in statuses.items():
        kind = "equivalent" if name in equivalent else "caught" if status in CAUGHT else status
        counts[module_of(name)][kind] += 1
    print("| module | mutants | caught | equivalent | survived | other | score |\n|---|---|---|---|---|---|---|")
    low, unrun = [], sorted(m for m, c in counts.items() if c["not checked"] == sum(c.values()) - c["equivalent"])
    for module in unrun:
        del counts[module]
    for module, c in sorted(counts.items()):
        total = sum(c.values())
        scored = total - c["equivalent"]
        other = total - c["caught"] - c["equivalent"] - c["survived"]
        score = c["caught"] / scored if scored else 1.0
        low += [module] if score < FLOOR else []
        print(f"| {module} | {total} | {c['caught']} | {c['equivalent']} | {c['survived']} | {other} | {score:.1%} |")
    everything = sum(counts.values(), Counter())
    scored = sum(everything.values()) - everything["equivalent"]
    caught = everything["caught"]
    stale = [name for name in stale if module_of(name) not in unrun]
    print(f"\nAll: {caught} of {scored} non-equivalent mutants caught ({caught / scored:.1%})")
    if unrun:
        print(f"\nNot run: {', '.join(unrun)}")
    for name in stale:
        print(f"listed as equivalent but not reported by mutmut (check it again): {name}", file=sys.stderr)
    return 1 if low or everything["not checked"] else 0


if __name__ == "__main__":
    sys.exit(main())
