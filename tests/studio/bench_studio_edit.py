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


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cli", required=True)
    ap.add_argument("--before")
    ap.add_argument("--trials", type=int, default=4)
    ap.add_argument("--key", default="speed0")
    ap.add_argument("scene")
    args = ap.parse_args()
    builds = {"after": args.cli, **({"before": args.before} if args.before else {})}
    studios = {}
    try:
        for name, cli in builds.items():
            proc, url = start_studio(cli, args.scene)
            ws = WebSocket(url)
            ws.sock.settimeout(600)  # a shot's model build sends nothing for minutes on a loaded machine
            hello = ws.recv_json("hello")
            studios[name] = {"proc": proc, "ws": ws, "value": dotted(hello["scene"], args.key), "trials": []}
        for s in studios.values():
            s["generation"] = s["ws"].wait_status(lambda m: m["stage"] == "finished", timeout=600)["generation"]
        for t in range(args.trials):
            for name, s in studios.items():
                value = round(s["value"] * (1.01 if t % 2 == 0 else 1.0), 12)
                r = one_edit(s["ws"], args.key, value, s["generation"])
                s["generation"] = r["generation"]
                s["trials"].append(r)
                print(f"{name} trial {t}: {json.dumps(r)}", file=sys.stderr)
    finally:
        for s in studios.values():
            s["ws"].close()
            stop_studio(s["proc"])
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
