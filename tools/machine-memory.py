#!/usr/bin/env python3
"""How much of this machine's memory a run uses, from outside the engine.

    tools/machine-memory.py mpiexec -np 4 build/flockmorph run SCENE -o OUT --quiet

Runs the command and samples, every 50 ms, the flockmorph processes it starts (its descendants):
prints the peak of their summed Pss (proportional set size: a page that several ranks map, such as
the model the ranks of a machine share, counts once, split among them) and each process's peak Rss
(which counts every shared page the process touched). Linux only (/proc/PID/smaps_rollup).
docs/scale-out.md ("One model a machine") has figures it measured.
"""
import os
import subprocess
import sys
import time


def descendants(root):
    parent = {}
    for pid in os.listdir("/proc"):
        if pid.isdigit():
            try:
                with open(f"/proc/{pid}/stat") as f:
                    parent[int(pid)] = int(f.read().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                pass
    below, grew = {root}, True
    while grew:
        more = {pid for pid, up in parent.items() if up in below and pid not in below}
        below |= more
        grew = bool(more)
    return below


def sizes(pid):
    """(Pss, Rss) of a flockmorph process in KiB, or None."""
    try:
        with open(f"/proc/{pid}/comm") as f:
            if f.read().strip() != "flockmorph":
                return None
        pss = rss = 0
        with open(f"/proc/{pid}/smaps_rollup") as f:
            for line in f:
                if line.startswith("Pss:"):
                    pss = int(line.split()[1])
                elif line.startswith("Rss:"):
                    rss = int(line.split()[1])
        return pss, rss
    except OSError:
        return None


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    run = subprocess.Popen(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    peak_sum, peak_rss = 0, {}
    while run.poll() is None:
        total = 0
        for pid in descendants(run.pid):
            got = sizes(pid)
            if got:
                total += got[0]
                peak_rss[pid] = max(peak_rss.get(pid, 0), got[1])
        peak_sum = max(peak_sum, total)
        time.sleep(0.05)
    err = run.stderr.read().decode(errors="replace")
    ranks = sorted(round(v / 1024) for v in peak_rss.values())
    print(f"rc={run.returncode} sum_pss_peak_MiB={peak_sum / 1024:.0f} rank_rss_peak_MiB={ranks}")
    if run.returncode:
        sys.stderr.write(err[-2000:])
    sys.exit(run.returncode)


if __name__ == "__main__":
    main()
