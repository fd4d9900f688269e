"""The time from an edit made while the model is built to the start of the edit's run: a benchmark
figure for docs/studio.md ("An edit during a build"), not a test.

    bench_studio_cancel.py --cli BUILD/flockmorph [--before OTHER/flockmorph] [--trials N]
                           [--rebuild-key n] [--delay S] SCENE.json

Starts `flockmorph studio SCENE` (and, with --before, a second studio of another build), waits for
the first runs, then in each trial and each studio in turn: an edit of REBUILD_KEY (n one up, then
back) that makes the whole model again, and DELAY seconds after that build starts (its shapes
message) an edit of speed0 (one percent up or back), timed to the status of the next generation,
which starts once the build in progress has stopped. Prints JSON: per studio the median seconds,
each trial's, and the edit's own build time (build_seconds of its run).
"""
import json
import statistics
import time

from bench_studio_edit import bench_args, dotted, run_alternating


def after_shapes(ws, generation):
    """Waits for the shapes message of a run after `generation` (sent as its build starts)."""
    while True:
        m = ws.recv_json(timeout=600)
        if m["type"] == "shapes" and m["generation"] > generation:
            return m["generation"]


def trial(s, args, t):
    ws = s["ws"]
    ws.send({"type": "set", "key": args.rebuild_key, "value": dotted(s["scene"], args.rebuild_key) + (1 if t % 2 == 0 else 0)})
    building = after_shapes(ws, s["generation"])
    time.sleep(args.delay)
    t0 = time.time()
    ws.send({"type": "set", "key": "speed0", "value": round(s["scene"]["speed0"] * (1.01 if t % 2 == 0 else 1.0), 12)})
    ws.wait_status(lambda m: m["generation"] > building, timeout=600)
    started = time.time() - t0
    end = ws.wait_status(lambda m: m["generation"] > building and m["stage"] in ("finished", "failed"), timeout=600)
    s["generation"] = end["generation"]
    return {"edit_to_run": started, "its_build_seconds": end["build_seconds"], "model_kept": end["model_kept"]}


def main():
    args, builds = bench_args(3, ("--rebuild-key", {"default": "n"}), ("--delay", {"type": float, "default": 0.3}))
    studios = run_alternating(builds, args.scene, args.trials, lambda s, t: trial(s, args, t))
    result = {"scene": args.scene, "delay": args.delay}
    for name, s in studios.items():
        tr = s["trials"]
        result[name] = {"edit_to_run_median": round(statistics.median(r["edit_to_run"] for r in tr), 2),
                        "edit_to_run": [round(r["edit_to_run"], 2) for r in tr],
                        "its_build_seconds": [round(r["its_build_seconds"], 2) for r in tr]}
    print(json.dumps(result))


if __name__ == "__main__":
    main()
