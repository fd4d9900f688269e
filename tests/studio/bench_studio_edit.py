"""The time from a studio edit to the new run's first frame, and to its end: a benchmark figure for
docs/studio.md ("An edit and the model"), not a test.

    bench_studio_edit.py --cli BUILD/flockmorph [--before OTHER/flockmorph] [--trials N]
                         [--key speed0] SCENE.json

Starts `flockmorph studio SCENE` (and, with --before, a second studio of another build on the same
scene), waits for the first runs, then sends N edits of KEY to each in turn (alternating, so that
the machine's load falls on both alike), the value stepping by 1 % each time, and times each from
the edit to the status that reports the new generation's first frame, and to its finished run.
Prints JSON: per studio the median seconds, each trial's, and whether the model was kept.
"""
import argparse
import json
import os
import statistics
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from studio_client import WebSocket, start_studio, stop_studio  # noqa: E402


def dotted(doc, key):
    """The value of a dotted key; a shot's groups.K.KEY that the group does not set is the top level's."""
    parts, node = key.split("."), doc
    for i, part in enumerate(parts):
        if isinstance(node, dict) and part not in node and parts[0] == "groups" and i >= 2:
            return dotted(doc, ".".join(parts[2:]))
        node = node[int(part)] if isinstance(node, list) else node[part]
    return node


def one_edit(ws, key, value, generation):
    t0 = time.time()
    ws.send({"type": "set", "key": key, "value": value})
    first = ws.wait_status(lambda m: m["generation"] > generation and m["frames"] >= 1, timeout=300)
    t1 = time.time()
    end = ws.wait_status(lambda m: m["generation"] > generation and m["stage"] in ("finished", "failed"), timeout=600)
    return {"first_frame": t1 - t0, "finished": time.time() - t0, "model_kept": end.get("model_kept"),
            "build_seconds": end.get("build_seconds"),
            "grids_kept": end.get("grids_kept"), "routes_kept": end.get("routes_kept"), "generation": end["generation"], "stage": end["stage"]}


def run_alternating(builds, scene, trials, one_trial):
    """Starts a studio of each build ({name: cli}) on scene, waits for the first runs, then runs the
    trials, the studios in turn so that the machine's load falls on them alike: one_trial(studio, t)
    returns trial t's record (a studio: its "ws", the "scene" its hello sent, the last "generation").
    Returns {name: studio}, each with its "trials"."""
    studios = {}
    try:
        for name, cli in builds.items():
            proc, url = start_studio(cli, scene)
            ws = WebSocket(url)
            ws.sock.settimeout(600)  # a shot's model build sends nothing for minutes on a loaded machine
            hello = ws.recv_json("hello")
            studios[name] = {"proc": proc, "ws": ws, "scene": hello["scene"], "trials": []}
        for s in studios.values():
            s["generation"] = s["ws"].wait_status(lambda m: m["stage"] == "finished", timeout=600)["generation"]
        for t in range(trials):
            for name, s in studios.items():
                s["trials"].append(one_trial(s, t))
                print(f"{name} trial {t}: {json.dumps(s['trials'][-1])}", file=sys.stderr)
    finally:
        for s in studios.values():
            s["ws"].close()
            stop_studio(s["proc"])
    return studios


def bench_args(trials, *options):
    """The benchmarks' command line: --cli, --before, --trials, SCENE and options ((name, kwargs)):
    (args, {name: cli} of the builds compared)."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--cli", required=True)
    ap.add_argument("--before")
    ap.add_argument("--trials", type=int, default=trials)
    for name, kwargs in options:
        ap.add_argument(name, **kwargs)
    ap.add_argument("scene")
    args = ap.parse_args()
    return args, {"after": args.cli, **({"before": args.before} if args.before else {})}


def main():
    args, builds = bench_args(4, ("--key", {"default": "speed0"}))

    def trial(s, t):
        value = round(dotted(s["scene"], args.key) * (1.01 if t % 2 == 0 else 1.0), 12)
        r = one_edit(s["ws"], args.key, value, s["generation"])
        s["generation"] = r["generation"]
        return r

    studios = run_alternating(builds, args.scene, args.trials, trial)
    result = {"scene": args.scene, "key": args.key}
    for name, s in studios.items():
        tr = s["trials"]
        result[name] = {"cli": builds[name], "first_frame_median": round(statistics.median(r["first_frame"] for r in tr), 2),
                        "finished_median": round(statistics.median(r["finished"] for r in tr), 2),
                        "first_frame": [round(r["first_frame"], 2) for r in tr],
                        "model_kept": [r["model_kept"] for r in tr],
                        "grids_kept": [r["grids_kept"] for r in tr], "routes_kept": [r["routes_kept"] for r in tr],
                        "build_seconds": [None if r["build_seconds"] is None else round(r["build_seconds"], 2) for r in tr]}
    print(json.dumps(result))


if __name__ == "__main__":
    main()
