#!/usr/bin/python3
"""The benchmarks' command lines and tools/bench-compare.sh (docs/performance.md), in a few seconds.

    test_bench_tools.py --build DIR --source DIR

- bench_suite and bench_step: --help and -h print the usage and exit 0 without benchmarking; an
  unknown option, a missing value and a bad value exit 1 (usage) naming the option, before any
  JSON is printed.
- bench_suite --mode flock at 2000 agents: one JSON document with the tetra mode's figures, every
  agent counted, and 1 and 2 threads in the same bits (deterministic true).
- bench_suite --mode flock --density-sweep 1 at 2000 agents: five points whose radius and mean
  neighbour count (the benchmark's own count) grow with the radius factor; refused for the morph.
- tools/bench-peers.sh: --help, and a bad value or an unknown option exit 1 naming it.
- tools/bench_compare.py: the medians, spreads and per-round ratios of made-up documents.
- tools/bench-compare.sh with this build on both sides (--base-build, --build, --no-rebuild): one
  round prints the header and the summary table; an option the base's sources do not name is
  refused with exit 2 before anything runs.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

failures = 0


def check(cond, what, detail=""):
    """Prints the check; on failure also `detail` (what the program said)."""
    global failures
    print(("ok   " if cond else "FAIL ") + what + ("" if cond or not detail else f"\n     {detail}"))
    failures += 0 if cond else 1


def run(cmd, **kw):
    env = dict(os.environ, OMP_WAIT_POLICY="passive")
    return subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=120, **kw)


def test_command_lines(build):
    for prog in ("bench_suite", "bench_step"):
        exe = os.path.join(build, prog)
        for flag in ("--help", "-h"):
            r = run([exe, flag])
            check(r.returncode == 0 and r.stdout.startswith(f"usage: {prog}"), f"{prog} {flag}: usage on stdout, exit 0")
        r = run([exe, "--agents", "10", "--bogus", "1"])
        check(r.returncode == 1 and f"{prog}: unknown option '--bogus'" in r.stderr and "usage:" in r.stderr
              and r.stdout == "", f"{prog} --bogus: exit 1 naming the option, nothing on stdout", r.stderr)
        r = run([exe, "--steps"])
        check(r.returncode == 1 and "--steps needs a value" in r.stderr, f"{prog} --steps: a missing value", r.stderr)
        r = run([exe, "--threads", "two"])
        check(r.returncode == 1 and "--threads wants a whole number" in r.stderr and "'two'" in r.stderr,
              f"{prog} --threads two: a bad value", r.stderr)
    r = run([os.path.join(build, "bench_suite"), "--mode", "fish"])
    check(r.returncode == 1 and "--mode wants one of morph, flock, not 'fish'" in r.stderr, "bench_suite --mode fish")
    r = run([os.path.join(build, "bench_suite"), "--mode", "flock", "--scenarios", "1"])
    check(r.returncode == 1 and "--scenarios is for --mode morph" in r.stderr, "bench_suite --mode flock --scenarios 1")


def test_flock_mode(build, source):
    r = run([os.path.join(build, "bench_suite"), "--mode", "flock", "--agents", "2000", "--steps", "2", "--threads", "2",
             "--machine", "0"])
    check(r.returncode == 0, "bench_suite --mode flock: exit 0", f"exit {r.returncode}: {r.stderr[-300:]}")
    try:
        doc = json.loads(r.stdout)
    except ValueError as e:
        check(False, f"bench_suite --mode flock: one JSON document ({e})")
        return
    runs = doc.get("runs", [])
    check(len(runs) == 1, "one run")
    if not runs:
        return
    run0 = runs[0]
    check(run0.get("mode") == "flock" and run0.get("agents") == 2000 and run0.get("threads") == 2
          and run0.get("steps") == 2, "mode, agents, threads, steps")
    check(run0.get("scene") == os.path.join(source, "examples/flock_suzanne_torus/scene.json"), "the default scene")
    check(run0.get("deterministic") is True, "1 and 2 threads end in the same bits")
    check(run0.get("in_flight", 0) + run0.get("bound", 0) == 2000, "every agent is flying, homing or bound")
    for key in ("agent_steps_per_second", "steps_per_second", "ns_per_agent_step", "thread_speedup",
                "bytes_per_agent", "preprocess_seconds"):
        check(isinstance(run0.get(key), (int, float)) and run0[key] > 0, f"{key} > 0")
    stages = run0.get("stage_ns_per_agent", {})
    check(set(stages) == {"step", "frame"} and stages["step"] > 0, "stage_ns_per_agent: step and frame")
    one = run0.get("one_thread", {})
    check(one.get("agent_steps_per_second", 0) > 0 and "step" in one.get("stage_ns_per_agent", {}), "one_thread")
    r = run([os.path.join(build, "bench_suite"), "--mode", "flock", "--agents", "2000", "--steps", "1", "--machine", "0",
             "--scene", os.path.join(source, "examples/castling/rook.json")])
    check(r.returncode == 2 and "needs a shape_flock scene" in r.stderr, "--mode flock refuses a morph scene", r.stderr)


def test_density_sweep(build, source):
    r = run([os.path.join(build, "bench_suite"), "--mode", "flock", "--density-sweep", "1", "--agents", "2000",
             "--steps", "1", "--threads", "1", "--sampling", "random", "--machine", "0"])
    check(r.returncode == 0, "bench_suite --density-sweep 1: exit 0", f"exit {r.returncode}: {r.stderr[-300:]}")
    try:
        runs = json.loads(r.stdout).get("runs", [])
    except ValueError as e:
        check(False, f"bench_suite --density-sweep 1: one JSON document ({e})")
        return
    factors = [p.get("radius_factor") for p in runs]
    check(factors == [0.7, 1.0, 1.5, 2.2, 3.2], "the sweep's five radius factors", str(factors))
    if len(runs) != 5:
        return
    # the radii scale with the factor, and so does the neighbour count the benchmark counts itself
    radius = [p["max_perception_radius"] for p in runs]
    check(all(abs(radius[i] / radius[0] - factors[i] / factors[0]) < 1e-3 for i in range(5)),
          "the largest perception radius scales with the factor", str(radius))
    neighbours = [p["mean_neighbours"] for p in runs]
    check(all(a < b for a, b in zip(neighbours, neighbours[1:])) and neighbours[-1] > 10 * neighbours[0],
          "the mean neighbour count grows with the radius (more than tenfold from 0.7 to 3.2)", str(neighbours))
    check(all(p.get("agent_steps_per_second", 0) > 0 and p.get("agents") == 2000 for p in runs), "every point timed")
    r = run([os.path.join(build, "bench_suite"), "--density-sweep", "1"])
    check(r.returncode == 1 and "--density-sweep is for --mode flock" in r.stderr, "bench_suite --density-sweep 1 (morph)")


def test_peers_command_line(source):
    script = os.path.join(source, "tools/bench-peers.sh")
    r = run([script, "--help"])
    check(r.returncode == 0 and "bench-peers.sh [--build DIR]" in r.stdout, "bench-peers.sh --help", r.stdout[:200])
    r = run([script, "--rounds", "two"])
    check(r.returncode == 1 and "--rounds takes a positive integer, not 'two'" in r.stderr, "bench-peers.sh --rounds two",
          r.stderr)
    r = run([script, "--bogus"])
    check(r.returncode == 1 and "unknown option --bogus" in r.stderr, "bench-peers.sh --bogus", r.stderr)


def test_summary(source, tmp):
    docs = [({"agent_steps_per_second": 100.0, "ns_per_agent_step": 10.0, "stage_ns_per_agent": {"grid": 0}},
             {"agent_steps_per_second": 150.0, "ns_per_agent_step": 8.0, "stage_ns_per_agent": {"grid": 0}}),
            ({"agent_steps_per_second": 120.0, "ns_per_agent_step": 9.0, "stage_ns_per_agent": {"grid": 0}},
             {"agent_steps_per_second": 240.0, "ns_per_agent_step": 6.0, "stage_ns_per_agent": {"grid": 0}}),
            ({"agent_steps_per_second": 110.0, "ns_per_agent_step": 10.0, "stage_ns_per_agent": {"grid": 0}},
             {"agent_steps_per_second": 110.0, "ns_per_agent_step": 10.0, "stage_ns_per_agent": {"grid": 0, "new": 3}})]
    files = []
    for k, (b, c) in enumerate(docs):
        for side, d in (("base", b), ("current", c)):
            path = os.path.join(tmp, f"{side}-{k}.json")
            with open(path, "w") as f:
                json.dump(d, f)
            files.append(path)
    r = run(["/usr/bin/python3", os.path.join(source, "tools/bench_compare.py")] + files)
    lines = {line.split(" | ")[0].lstrip("| "): line for line in r.stdout.splitlines()}
    check(r.returncode == 0, "bench_compare.py: exit 0")
    # base 100, 120, 110: median 110; current 150, 240, 110: median 150; ratios 1.5, 2, 1: median 1.5
    check(lines.get("agent_steps_per_second") == "| agent_steps_per_second | 110 (100–120) | 150 (110–240) | 1.500 (1.000–2.000) |",
          "medians, spreads and ratios", r.stdout + r.stderr)
    check("stage_ns_per_agent.grid" not in lines, "a figure 0 everywhere is left out")
    check("stage_ns_per_agent.new" not in lines and "only in the current: stage_ns_per_agent.new" in r.stdout,
          "a figure only the current prints is named, not tabled", r.stdout)


def test_compare_script(build, source):
    script = os.path.join(source, "tools/bench-compare.sh")
    both = [script, "--base-build", build, "--build", build, "--no-rebuild", "--rounds", "1"]
    args = ["--", "--mode", "flock", "--agents", "2000", "--steps", "2", "--threads", "2", "--machine", "0"]
    r = run(both + args)
    check(r.returncode == 0, "bench-compare.sh: exit 0", f"exit {r.returncode}: {r.stderr[-300:]}")
    out = r.stdout
    check("machine: " in out and "avx2 " in out and "avx512f " in out, "the processor and its SIMD flags")
    runs = [line for line in out.splitlines() if line.strip().startswith("run:")]
    check(len(runs) == 2 and all("OMP_WAIT_POLICY=passive" in line and f"{build}/bench_suite --mode flock --agents 2000"
                                 in line for line in runs), "the exact commands, with the OpenMP environment")
    check("| figure | base: median (min–max) |" in out, "the summary table")
    row = [line for line in out.splitlines() if line.startswith("| runs[agents=2000].agent_steps_per_second |")]
    check(len(row) == 1 and row[0].count("|") == 5, "the throughput's row", out)
    check("NOT DETERMINISTIC" not in out, "both sides deterministic")
    r = run(both + ["--", "--agents", "2000", "--no-such-option", "1"])
    check(r.returncode == 2 and "has no option --no-such-option" in r.stderr and "round 1" not in r.stdout,
          "an option the base lacks: exit 2 before running", f"exit {r.returncode}: {r.stderr[-300:]}")
    r = run([script, "--rounds", "0"])
    check(r.returncode == 1 and "--rounds wants a whole number" in r.stderr, "bench-compare.sh --rounds 0: usage")
    r = run(both + ["--bench-source", "current", "--", "--agents", "2000"])
    check(r.returncode == 1 and "not with --base-build" in r.stderr, "--bench-source current needs a base to build", r.stderr)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", required=True)
    ap.add_argument("--source", required=True)
    a = ap.parse_args()
    test_command_lines(a.build)
    test_flock_mode(a.build, a.source)
    test_density_sweep(a.build, a.source)
    test_peers_command_line(a.source)
    with tempfile.TemporaryDirectory() as tmp:
        test_summary(a.source, tmp)
    test_compare_script(a.build, a.source)
    print(f"{failures} failure(s)")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
