#!/usr/bin/python3
"""Plots the shape flock's density sweep (agent-steps per second against the mean number of
neighbours, bench_suite --density-sweep 1) beside FLAME GPU 2's published "circles" figures at about
10^6 agents.

    build/bench_suite --mode flock --density-sweep 1 --agents 1000000 --steps 4 --threads 2 \\
        --sampling random > sweep.json
    /usr/bin/python3 tools/plot_density.py sweep.json docs/images/density_sweep.png

FLAME GPU 2's figures are the s_step_mean of its circles benchmark (Spatial3D messaging with
run-time compilation, 200 steps, seatbelts off), from the raw CSVs published with
github.com/FLAMEGPU/FLAMEGPU2-circles-benchmark (commit d5621f9, sample/): the fixed-density
experiment at 1,000,000 agents (density 1, communication radius 2; the H100 PCIe, A100 SXM4 and V100
SXM2 runs with CUDA 11.8 in sample/comparisons/h100-a100-v100-fixed-density) and the variable-density
experiment (radius 2, densities 2, 3 and 4, the populations nearest 10^6: 986,078, 1,029,000 and
1,000,188 agents; H100 PCIe and V100 SXM2 runs of 2.0.0-rc). A circles agent's neighbours within
its radius number density * 4/3 pi r^3 = 33.5 per unit of density; agent-steps/s = agents /
s_step_mean. Richmond et al., "FLAME GPU 2: A framework for flexible and performant agent based
simulation on GPUs", Software: Practice and Experience 53(8), 2023, doi:10.1002/spe.3207.

Needs matplotlib (Debian's python3-matplotlib: FM_WITH_PEERS=1 tools/setup.sh installs it); uses Debian's
/usr/bin/python3.
"""
import json
import math
import os
import sys

# (GPU, mean neighbours within the radius, agents, s per step) from the CSVs named above
FLAME_GPU_2 = [
    ("H100 PCIe", 1, 1000000, 0.002122),
    ("H100 PCIe", 2, 986078, 0.003898),
    ("H100 PCIe", 3, 1029000, 0.005612),
    ("H100 PCIe", 4, 1000188, 0.006303),
    ("A100 SXM4", 1, 1000000, 0.002701),
    ("V100 SXM2", 1, 1000000, 0.003720),
    ("V100 SXM2", 2, 986078, 0.008465),
    ("V100 SXM2", 3, 1029000, 0.011966),
    ("V100 SXM2", 4, 1000188, 0.013885),
]
NEIGHBOURS_PER_DENSITY = 4.0 / 3.0 * math.pi * 2.0 ** 3  # radius 2


def flame_points():
    """{gpu: [(mean neighbours, agent-steps/s)]}"""
    out = {}
    for gpu, density, agents, s_step in FLAME_GPU_2:
        out.setdefault(gpu, []).append((density * NEIGHBOURS_PER_DENSITY, agents / s_step))
    return out


def sweep_points(path):
    """[(mean neighbours, agent-steps/s)] of a bench_suite --density-sweep JSON, and its machine"""
    try:
        with open(path) as f:
            bench = json.load(f)
        runs = bench.get("runs", []) if isinstance(bench, dict) else []
        points = sorted((r["mean_neighbours"], r["agent_steps_per_second"]) for r in runs)
    except (OSError, ValueError, KeyError, TypeError) as e:
        sys.exit(f"plot_density: {path}: not a bench_suite --density-sweep JSON ({e})")
    if not points:
        sys.exit(f"plot_density: {path} holds no density sweep (bench_suite --density-sweep 1)")
    threads = runs[0]["threads"]
    machine = bench.get("machine", {}).get("cpu", "")
    return points, threads, machine


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    points, threads, machine = sweep_points(sys.argv[1])
    fig, ax = plt.subplots(figsize=(7, 4.4), dpi=120)
    ax.plot([p[0] for p in points], [p[1] for p in points], "o-", color="black",
            label=f"flockmorph shape flock, {threads} CPU threads" + (f" ({machine})" if machine else ""))
    for (gpu, pts), marker in zip(sorted(flame_points().items()), "s^v"):
        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker + "--", label=f"FLAME GPU 2 circles, {gpu}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("mean neighbours within the (largest) radius")
    ax.set_ylabel("agent-steps per second, ~10^6 agents")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    partial = sys.argv[2] + ".partial.png"  # renamed when whole: no half-written image under the name
    fig.savefig(partial)
    os.replace(partial, sys.argv[2])


if __name__ == "__main__":
    main()
