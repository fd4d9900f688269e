#!/usr/bin/python3
"""The figures of tools/bench-compare.sh: a base's and the current tree's benchmark JSON, round by round.

    bench_compare.py [--figures REGEX] [--round K] BASE1.json CURRENT1.json [BASE2.json CURRENT2.json ...]

Every JSON document (bench_suite's, bench_step's or any benchmark's) is flattened into figures named
by their path: `runs[agents=100000].one_thread.agent_steps_per_second`, `stage_ns_per_agent.grid`
(a list's entries are named by their "agents", "scenario" or "name" member, else their index).
With --round K it prints round K, the last pair given, in short (the agent-steps per second); without
it, a Markdown table over all the pairs: each figure's median and min-max for the base and the
current tree, and the median and min-max of the rounds' ratios current/base (a round's two runs ran
one after the other, so their ratio is the steadier figure on a machine whose load drifts). It also
names any run whose "deterministic" is false, any text or true/false figure in which the two
sides differ, and the figures that only one side prints (a stage the base did not time). Standard library only (Debian's /usr/bin/python3).
"""
import argparse
import json
import re
import statistics
import sys

# The figures shown by default: throughput, time per agent-step and per stage, speedups, memory,
# and the machine's measured bandwidth, peak and clock (they show a loaded machine).
DEFAULT_FIGURES = (r"(^|\.)(agent_steps_per_second|steps_per_second|ns_per_agent_step|cpu_ns_per_agent_step"
                   r"|thread_speedup|bytes_per_agent|idle_ns_per_agent|roofline_fraction|stream_triad_gbps|peak_gflops|clock_ghz)$"
                   r"|stage_ns_per_agent\.")
ROUND_FIGURES = r"(^|\.)agent_steps_per_second$"
LABELS = ("agents", "scenario", "name")


def flatten(value, path="", out=None):
    """Leaf path -> value, in document order."""
    out = {} if out is None else out
    if isinstance(value, dict):
        for key, item in value.items():
            flatten(item, f"{path}.{key}" if path else key, out)
    elif isinstance(value, list):
        for i, item in enumerate(value):
            label = next((f"{k}={item[k]}" for k in LABELS if isinstance(item, dict) and k in item), str(i))
            flatten(item, f"{path}[{label}]", out)
    else:
        out[path] = value
    return out


def load(path):
    try:
        with open(path, encoding="utf-8") as f:
            return flatten(json.load(f))
    except (OSError, ValueError) as e:
        sys.exit(f"bench_compare.py: {path}: not a JSON document ({e})")


def number(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def fmt(v):
    return f"{v:.4g}" if number(v) else str(v)


def spread(values, f=fmt):
    """The median and, over more than one round, the min–max in brackets."""
    if len(values) == 1:
        return f(values[0])
    return f"{f(statistics.median(values))} ({f(min(values))}–{f(max(values))})"


def figures(pairs, pattern):
    """The numeric figures that match `pattern`, are in every document and are not 0 in all of them
    (a stage the scene does not have, a machine figure that was not measured), in the base's order."""
    regex = re.compile(pattern)
    names = [k for k, v in pairs[0][0].items() if number(v) and regex.search(k)]
    names = [k for k in names if all(number(b.get(k)) and number(c.get(k)) for b, c in pairs)]
    return [k for k in names if any(b[k] or c[k] for b, c in pairs)]


def ratio(b, c):
    return c / b if b else float("nan")


def fmt_ratio(r):
    return "—" if r != r else f"{r:.3f}"


def print_round(k, base, current, pattern):
    for name in figures([(base, current)], pattern):
        b, c = base[name], current[name]
        print(f"  round {k}  {name}: base {fmt(b)}  current {fmt(c)}  current/base {fmt_ratio(ratio(b, c))}")


def print_summary(pairs, pattern):
    names = figures(pairs, pattern)
    print("| figure | base: median (min–max) | current: median (min–max) | current/base per round: median (min–max) |")
    print("|---|---:|---:|---:|")
    for name in names:
        bs = [b[name] for b, _ in pairs]
        cs = [c[name] for _, c in pairs]
        rs = [ratio(b, c) for b, c in zip(bs, cs)]
        rs = [r for r in rs if r == r] or [float("nan")]  # a round whose base is 0 has no ratio
        print(f"| {name} | {spread(bs)} | {spread(cs)} | {spread(rs, fmt_ratio)} |")
    lower = [n for n in names if re.search(r"ns_per|bytes_per", n)]
    if lower:
        print("\nns and bytes figures: lower is better (a ratio below 1 is a gain); the others: higher is better.")


def print_notes(pairs, pattern):
    regex = re.compile(pattern)
    sides = {"base": [b for b, _ in pairs], "current": [c for _, c in pairs]}
    named = {side: {k for d in docs for k, v in d.items() if number(v) and regex.search(k)} for side, docs in sides.items()}
    for side, other in (("base", "current"), ("current", "base")):
        only = sorted(named[side] - named[other])
        if only:
            print(f"only in the {side}: {', '.join(only)}")
    for k, (base, current) in enumerate(pairs, 1):
        for side, doc in (("base", base), ("current", current)):
            for name, v in doc.items():
                if re.search(r"(^|\.)deterministic$", name) and v is not True:
                    print(f"NOT DETERMINISTIC: {side}, round {k}: {name} = {fmt(v)}")
    base, current = pairs[0]
    for name, v in base.items():
        w = current.get(name)
        if not number(v) and w is not None and not number(w) and v != w and not name.endswith("scene"):
            print(f"differs: {name}: base {fmt(v)}, current {fmt(w)}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--figures", default=None, help="regular expression over the figures' paths")
    ap.add_argument("--round", type=int, default=0, help="print round K (the last pair) in short")
    ap.add_argument("files", nargs="+")
    a = ap.parse_args()
    if len(a.files) % 2:
        ap.error("give the JSON files in pairs: base, current")
    docs = [load(p) for p in a.files]
    pairs = list(zip(docs[0::2], docs[1::2]))
    if a.round:
        print_round(a.round, *pairs[-1], a.figures or ROUND_FIGURES)
        return
    if not figures(pairs, a.figures or DEFAULT_FIGURES):
        sys.exit("bench_compare.py: no figure matches in every document")
    print_summary(pairs, a.figures or DEFAULT_FIGURES)
    print_notes(pairs, a.figures or DEFAULT_FIGURES)


if __name__ == "__main__":
    main()
