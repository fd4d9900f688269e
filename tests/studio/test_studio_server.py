"""test_studio_server: `flockmorph studio` under bad input, without a browser (docs/studio.md).

    test_studio_server.py --cli FLOCKMORPH --source REPO --tmp DIR

HTTP: the token on every request, a foreign Origin refused, only the page's own files. The
WebSocket: a wrong token or a foreign Origin gets no connection; malformed JSON, a message that is
not an object, an unknown type, a missing or mistyped field, a huge, binary or fragmented message,
scene edits the loader refuses (the error names the key) and edits naming other files each get an
error message, and the connection still answers after them. A run the model build refuses says
why; twenty edits in a row make at most three runs; two clients edit at once and agree; clients
that vanish mid-run (one mid-way through a frame claiming a terabyte) leave the studio running.
An edit of the path keeps the model (TetGen's tets), one of the target's placement does not.
Save writes the file atomically, and `flockmorph run` of it writes the frames the studio streamed,
byte for byte, as does the Render button (refused before a save): the run compared is one whose
model was kept. The same for a shape flock whose samples and match were kept, and for a shot
(a scene with groups) edited live: a group's key changes its run, a bad one is named, a group's
speed0 keeps every group's model and moving one group's target builds that group alone again; a
shape-flock shot chained from one group's formed shape keeps both, and builds both again when the
first is sampled anew. That cache
played back gives the reader's frames and refuses edits. The studio never crashes and exits 0 on
SIGTERM.
"""
import argparse
import glob
import hashlib
import json
import os
import shutil
import struct
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from studio_client import WebSocket, http_get, start_studio, stop_studio  # noqa: E402

FAILURES = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what, flush=True)
    if not ok:
        FAILURES.append(what)


def error_of(ws, message=None, raw=None):
    """The error message the studio answers with."""
    if raw is not None:
        ws.send_frame(*raw) if isinstance(raw, tuple) else ws.send_frame(1, raw)
    else:
        ws.send(message)
    return ws.recv_json("error", timeout=20)["message"]


def finished(ws, after=0):
    return ws.wait_status(lambda m: m["generation"] > after and m["stage"] in ("finished", "failed"), timeout=60)


def check_http(url, port, token):
    base = url.rsplit("/", 2)[0]
    status, _ = http_get(url)
    check(status in (200, 500), f"the page with the token answers ({status})")
    check(http_get(base + "/")[0] == 403, "no token: 403")
    check(http_get(base + "/" + "0" * 32 + "/")[0] == 403, "a wrong token: 403")
    check(http_get(url + "app.js", {"Origin": "http://evil.example"})[0] == 403, "a foreign Origin: 403")
    check(http_get(url + "..%2f..%2fetc%2fpasswd")[0] in (403, 404), "a path out of the page's folder is refused")
    check(http_get(url + ".hidden")[0] == 404, "a hidden file name is refused")


def check_refusals(url):
    check(WebSocket(url, origin="http://evil.example").status != 101, "a WebSocket from a foreign Origin is refused")
    wrong = url.replace(url.split("/")[3], "f" * 32)
    check(WebSocket(wrong).status != 101, "a WebSocket with a wrong token is refused")
    own = url.split("/")[0] + "//" + url.split("/")[2]
    ws = WebSocket(url, origin=own)
    check(ws.status == 101, "a WebSocket from the studio's own origin is accepted")
    ws.close()


def check_bad_messages(ws):
    e = error_of(ws, raw=b'{"type": "frame", "k": ')
    check("malformed JSON" in e, f"malformed JSON: {e}")
    e = error_of(ws, raw=b"[1, 2, 3]")
    check('"type"' in e, f"not an object with a type: {e}")
    e = error_of(ws, {"type": "launch_missiles"})
    check("launch_missiles" in e, f"an unknown type is named: {e}")
    e = error_of(ws, raw=b'{"type": "frame", "k": 1, "k": 2}')
    check("malformed JSON" in e, f"a duplicate key: {e}")
    e = error_of(ws, raw=(1, b" " * 300000))
    check("300000 bytes" in e, f"a huge message: {e}")
    e = error_of(ws, raw=(2, b"\x00\x01\x02"))
    check("binary" in e, f"a binary message: {e}")
    ws.send_frame(1, b'{"type": ', fin=False)
    e = error_of(ws, raw=(0, b'"frame", "k": 0}'))
    check("fragmented" in e, f"a fragmented message: {e}")
    e = error_of(ws, {"type": "frame", "k": "seven"})
    check('"k"' in e, f"a mistyped frame number: {e}")
    e = error_of(ws, {"type": "frame", "k": 10 ** 9})
    check("not simulated yet" in e, f"a frame past the run: {e}")
    e = error_of(ws, {"type": "set", "key": "speed0"})
    check('"value"' in e, f"an edit without a value: {e}")
    e = error_of(ws, {"type": "set", "key": "speed0", "value": -1})
    check("speed0" in e and "out of range" in e, f"an invalid edit names the key: {e}")
    e = error_of(ws, {"type": "set", "key": "mde.d_min", "value": "far"})
    check("mde.d_min" in e, f"a mistyped nested edit names the key: {e}")
    e = error_of(ws, {"type": "set", "key": "speeed0", "value": 3})
    check("speeed0" in e, f"an unknown key is named: {e}")
    e = error_of(ws, {"type": "set", "key": "source.mesh", "value": "/etc/passwd"})
    check("/etc/passwd" in e and "refused" in e, f"an edit that names another file is refused: {e}")
    e = error_of(ws, {"type": "set", "key": "output.cache", "value": "elsewhere.fmc"})
    check("elsewhere.fmc" in e and "refused" in e, f"an edit of the cache's name is refused: {e}")
    e = error_of(ws, {"type": "hello", "protocol": 99})
    check("protocol 1" in e, f"another protocol version: {e}")
    head, attrs = ws.frame(0)
    check(head["frame"] == 0 and 1 in attrs, "after all that the connection still serves frames")


def check_failed_run(url):
    """An edit the loader accepts but the model build refuses (n below TetGen's count): the run
    fails, the page hears why, and the next edit runs again."""
    ws = WebSocket(url)
    ws.recv_json("hello")
    start = ws.wait_status(lambda m: m["stage"] == "finished", timeout=60)["generation"]
    ws.send({"type": "set", "key": "n", "value": 10})
    failed = ws.wait_status(lambda m: m["generation"] > start and m["stage"] in ("failed", "finished"), timeout=60)
    check(failed["stage"] == "failed" and "n: 10 is smaller" in failed["failure"], f"a failed run says why: {failed['failure']}")
    ws.send({"type": "set", "key": "n", "value": None})
    again = ws.wait_status(lambda m: m["generation"] > failed["generation"] and m["stage"] in ("failed", "finished"), timeout=60)
    check(again["stage"] == "finished" and not again["failure"], "the next edit runs again")
    ws.close()


def edited_run(ws, key, value, after):
    """The finished status of the run an edit makes."""
    ws.send({"type": "set", "key": key, "value": value})
    return ws.wait_status(lambda m: m["generation"] > after and m["stage"] in ("finished", "failed"), timeout=60)


def check_model_keep(url):
    """An edit that leaves the meshes, the tetgen keys and n as they were keeps the model's tets
    (the build takes no TetGen run); one that moves the target makes them again."""
    ws = WebSocket(url)
    ws.recv_json("hello")
    start = ws.wait_status(lambda m: m["stage"] == "finished", timeout=60)["generation"]
    path = edited_run(ws, "path.points", [[0.0, -5.0, 7.5]], start)
    check(path["stage"] == "finished" and path["model_kept"] is True,
          f"a path edit keeps the model (built in {path['build_seconds']:.3f} s)")
    moved = edited_run(ws, "target.translate", [16.0, 0.0, 0.0], path["generation"])
    check(moved["stage"] == "finished" and moved["model_kept"] is False,
          f"moving the target builds the model again ({moved['build_seconds']:.3f} s)")
    edited_run(ws, "target.translate", [15.0, 0.0, 0.0], moved["generation"])  # back, for the checks after
    ws.close()


def current_status(url):
    """The status a page that connects now is sent."""
    ws = WebSocket(url)
    ws.recv_json("hello")
    status = ws.wait_status(lambda m: True, timeout=10)
    ws.close()
    return status


def check_unrun_edits(url):
    """An edit that leaves what the run simulates as it was (a value set to the one it has, only the
    cache's compression) starts no run: the finished run and its frames stand. (check_truth then
    runs the saved scene, compression edited, against the frames streamed.) An edit after it runs."""
    ws = WebSocket(url)
    hello = ws.recv_json("hello")
    done = ws.wait_status(lambda m: m["stage"] == "finished", timeout=60)
    last = hashlib.sha256(ws.frame(done["frames"] - 1)[1][1]).hexdigest()
    for i, (key, value) in enumerate((("speed0", hello["scene"]["speed0"]), ("output.compression_level", 5))):
        ws.send({"type": "set", "key": key, "value": value})
        told = ws.wait_status(lambda m: True, timeout=10)  # the accepted edit's status
        time.sleep(0.3)  # past the 50 ms the worker waits for edits to settle: a run would have started
        now = current_status(url)
        check(told["generation"] == now["generation"] == done["generation"] and now["stage"] == "finished"
              and now["frames"] == done["frames"] and now["unrun_edits"] == done["unrun_edits"] + i + 1,
              f"set {key}={value} leaves the run as it was: no run (generation {now['generation']}, {now['stage']})")
    check(hashlib.sha256(ws.frame(done["frames"] - 1)[1][1]).hexdigest() == last, "the unrun edits' frames stand")
    ran = edited_run(ws, "speed0", hello["scene"]["speed0"] + 0.5, done["generation"])
    check(ran["stage"] == "finished" and ran["unrun_edits"] == done["unrun_edits"] + 2, "an edit that changes the scene runs it")
    ws.close()


def check_two_editors(url, ws):
    a, b = WebSocket(url), WebSocket(url)
    a.recv_json("hello"), b.recv_json("hello")
    a.send({"type": "set", "key": "speed0", "value": 13.0})
    b.send({"type": "set", "key": "speed0", "value": 15.0})
    last_a = [a.recv_json("scene")["scene"]["speed0"] for _ in range(2)][-1]
    last_b = [b.recv_json("scene")["scene"]["speed0"] for _ in range(2)][-1]
    check(last_a == last_b and last_a in (13.0, 15.0), f"two editors see the same last edit ({last_a}, {last_b})")
    a.close(), b.close()
    return last_a


def check_burst(url):
    """A slider drag: twenty edits in a row run the one in progress and the last, not twenty."""
    ws = WebSocket(url)
    ws.recv_json("hello")
    start = ws.wait_status(lambda m: m["stage"] == "finished", timeout=60)["generation"]
    values = [round(10 + 0.1 * i, 1) for i in range(20)]
    for v in values:
        ws.send({"type": "set", "key": "speed0", "value": v})
    scenes, status, deadline = [], None, time.time() + 60
    while time.time() < deadline and not (len(scenes) == 20 and status and status["stage"] == "finished"
                                          and status["generation"] > start and not ws.readable(1.0)):
        m = ws.recv_json(timeout=60)
        if m["type"] == "scene":
            scenes.append(m["scene"]["speed0"])
        elif m["type"] == "status":
            status = m
    check(scenes == values, "every edit of the burst was applied, in order")
    runs = status["generation"] - start
    check(runs <= 3, f"twenty edits in a row made {runs} runs (at most 3: the one in progress, perhaps one more, the last)")
    check(status["stage"] == "finished", "the last edit's run finished")
    ws.close()


def check_vanishing_clients(url):
    c = WebSocket(url)
    c.recv_json("hello")
    c.send({"type": "set", "key": "launch_rate", "value": 900})
    c.send({"type": "frame", "k": 0})
    c.close()  # mid-run, with a frame on its way
    d = WebSocket(url)
    d.sock.sendall(bytes([0x81, 0x80 | 127]) + struct.pack(">Q", 1 << 40) + os.urandom(4) + b"x" * 1000)
    d.sock.close()  # a frame that claims a terabyte, cut off


def streamed_and_run(args, ws, scene, frames, out):
    """(SHA-256 of each frame the studio streams, of each frame `flockmorph run` of the scene writes)."""
    streamed = []
    for k in range(frames):
        attrs = ws.frame(k)[1]
        streamed.append(hashlib.sha256(attrs[1 if 1 in attrs else 2]).hexdigest())  # tet vertices, or positions
    run = subprocess.run([args.cli, "run", scene, "-o", out, "--quiet"], capture_output=True, text=True)
    check(run.returncode == 0, f"flockmorph run of the saved scene ({run.stderr.strip()})")
    facts = subprocess.run([sys.executable, os.path.join(HERE, "cache_facts.py"), os.path.join(out, "frames.fmc")],
                           capture_output=True, text=True, check=True)
    return streamed, json.loads(facts.stdout)["sha256"]


def check_truth(args, ws, scene, tmp):
    """Save, then `flockmorph run` of the saved file against every frame the studio streams."""
    status = ws.wait_status(lambda m: m["stage"] == "finished", timeout=60)  # the last edit's run
    check(status["model_kept"] is True, "the run compared below (launch_rate edited) kept the model")
    e = error_of(ws, {"type": "render"})
    check("save the scene first" in e, f"render before a save is refused: {e}")
    ws.send({"type": "save"})
    saved = ws.recv_json("saved")
    check(saved["path"] == scene, "save answers with the scene's path")
    check(not os.path.exists(scene + ".partial"), "save leaves no partial file")
    streamed, written = streamed_and_run(args, ws, scene, status["frames"], os.path.join(tmp, "out"))
    check(written == streamed, f"run wrote the {len(written)} frames the studio streamed ({len(streamed)}), byte for byte")
    ws.send({"type": "render"})
    end = ws.recv_json("render")
    while end["state"] == "running":
        end = ws.recv_json("render", timeout=60)
    check(end["state"] == "finished" and end["exit"] == 0, f"Render ran flockmorph run of the saved scene ({end})")
    facts = subprocess.run([sys.executable, os.path.join(HERE, "cache_facts.py"), os.path.join(args.render, "frames.fmc")],
                           capture_output=True, text=True)
    check(facts.returncode == 0 and json.loads(facts.stdout)["sha256"] == written,
          "Render's cache is the frames the studio streamed, byte for byte")


def check_saved_run(args, ws, scene, frames, out, what):
    """Save, then `flockmorph run` of the file writes the frames the studio streamed."""
    ws.send({"type": "save"})
    ws.recv_json("saved")
    streamed, written = streamed_and_run(args, ws, scene, frames, out)
    check(written == streamed, f"{what}: run of the saved file wrote the {len(written)} frames the studio streamed "
                               f"({len(streamed)}), byte for byte")


def check_stopped(proc, what):
    code, err = stop_studio(proc)
    check(code == 0 and "AddressSanitizer" not in err and "runtime error" not in err,
          f"{what}: the studio exits 0, no sanitizer report")


def studio_on(args, tmp, name, doc):
    """Writes doc as tmp/name and starts a studio on it: (the scene's path, the process, its address)."""
    scene = os.path.join(tmp, name)
    with open(scene, "w") as f:
        json.dump(doc, f)
    return (scene, *start_studio(args.cli, scene))


def check_flock_keep(args, tmp):
    """A shape flock routed round a small sphere: an edit of n samples again and keeps the obstacles'
    grid (its meshes, reach k_a and voxel are as they were) but routes R again (its margin, the flock's
    radius, changed); one of the path's point routes again on the kept route grid; one of the boids'
    weights keeps the samples, the match, the grid and the route. Save, and `flockmorph run` writes the
    kept run's frames byte for byte (a route made on the kept route grid, kept since)."""
    scene, proc, url = studio_on(args, tmp, "flock.json", {
        "mode": "shape_flock", "source": {"mesh": "cylinder.obj", "translate": [-15.0, 0.0, 0.0]},
        "target": {"mesh": "sphere.obj", "translate": [15.0, 0.0, 0.0]}, "n": 300, "speed0": 8.0,
        "time": {"frame_rate": 24, "frame_limit": 24}, "path": {"points": [[0.0, -6.0, 7.0]]}, "seed": 9,
        "obstacles": {"meshes": [{"mesh": "sphere.obj", "scale": 0.3, "translate": [0.0, -3.0, 3.5]}], "k_a": 1.0, "voxel": 0.5}})
    try:
        ws = WebSocket(url)
        ws.recv_json("hello")
        first = finished(ws)
        check(first["grids_kept"] == 0 and first["routes_kept"] == 0, "shape flock: the first run makes the grid and the route")
        more = edited_run(ws, "n", 320, first["generation"])
        check(more["stage"] == "finished" and more["model_kept"] is False, "shape flock: an edit of n samples again")
        check(more["grids_kept"] == 1 and more["routes_kept"] == 0,
              f"shape flock: ... keeps the obstacles' grid ({more['grids_kept']}) and routes R again ({more['routes_kept']})")
        moved = edited_run(ws, "path.points", [[0.0, -6.5, 7.0]], more["generation"])
        check(moved["stage"] == "finished" and moved["model_kept"] is True and moved["grids_kept"] == 1
              and moved["routes_kept"] == 0, "shape flock: a path edit keeps the samples and the grid and routes R again")
        kept = edited_run(ws, "shape_flock.cohesion.weight", [0.2, 0.4], moved["generation"])
        check(kept["stage"] == "finished" and kept["model_kept"] is True,
              f"shape flock: a boids edit keeps the samples and the match (built in {kept['build_seconds']:.3f} s)")
        check(kept["grids_kept"] == 1 and kept["routes_kept"] == 1,
              f"shape flock: ... and the obstacles' grid ({kept['grids_kept']}) and routed R ({kept['routes_kept']})")
        check_saved_run(args, ws, scene, kept["frames"], os.path.join(tmp, "flock_out"), "shape flock (all kept)")
        plain = os.path.join(tmp, "flock_plain")  # the same scene, R as the user drew it: a frame is enough
        subprocess.run([args.cli, "run", scene, "-o", plain, "--quiet", "--set", "obstacles.route=false",
                        "--set", "time.frame_limit=1"], check=True, capture_output=True)
        lengths = [json.load(open(os.path.join(d, "stats.json")))["shape_flock"]["path_length"] for d in (os.path.join(tmp, "flock_out"), plain)]
        check(lengths[0] > lengths[1] + 1, f"shape flock: R was routed round the sphere (length {lengths[0]:.2f}, "
                                           f"{lengths[1]:.2f} unrouted)")
        ws.close()
    finally:
        check_stopped(proc, "shape flock")


def check_cancelled_build(args, tmp):
    """An edit made while the model is built (a shape flock of 4000 points: the mosaic's sampling is
    most of a build of seconds) stops the build at its next stage boundary, so that the edit's run
    starts at once, not when the build would have ended: the edit's own build, which samples again
    (nothing of the cancelled one was kept), measures what the wait would have been. The cancelled run
    streamed no frame and left no partial file in the studio's scratch folder."""
    before = set(glob.glob("/tmp/flockmorph-studio-*"))
    scene, proc, url = studio_on(args, tmp, "long_build.json", {
        "mode": "shape_flock", "source": {"mesh": "cylinder.obj", "translate": [-15.0, 0.0, 0.0]},
        "target": {"mesh": "sphere.obj", "translate": [15.0, 0.0, 0.0]}, "n": 4000, "speed0": 8.0,
        "time": {"frame_rate": 24, "frame_limit": 1}, "seed": 9})
    try:
        ws = WebSocket(url)
        ws.recv_json("hello")
        building = ws.recv_json("status")  # sent on connecting, then the shapes as the first run's build starts
        while (m := ws.recv_json(timeout=30))["type"] != "shapes":
            building = m if m["type"] == "status" else building
        t0 = time.time()
        ws.send({"type": "set", "key": "speed0", "value": 9.0})
        ws.wait_status(lambda m: m["generation"] > building["generation"], timeout=120)
        waited = time.time() - t0
        end = finished(ws, building["generation"])
        check(building["stage"] == "building" and building["frames"] == 0, "cancelled build: the edit came during the build")
        check(end["stage"] == "finished" and end["model_kept"] is False,
              f"cancelled build: the edit's run built the model afresh ({end['stage']}, kept {end['model_kept']})")
        check(waited < 0.5 * end["build_seconds"], f"cancelled build: the edit's run started {waited:.2f} s after it, "
                                                   f"under half the {end['build_seconds']:.2f} s a build takes")
        scratch = sorted(set(glob.glob("/tmp/flockmorph-studio-*")) - before)
        if len(scratch) == 1:  # else another test's studio started beside it: which folder is this one's?
            partial = [f for f in os.listdir(scratch[0]) if "partial" in f]
            check(not partial, f"cancelled build: no partial file in the scratch folder ({scratch[0]}: {partial})")
        ws.close()
    finally:
        check_stopped(proc, "cancelled build")


def check_shot_edit(args, tmp):
    """A shot: its groups are read from the edited scene, not the file. An edit of one group's key
    changes the run's frames; an invalid one names the group's key; Save, and `flockmorph run` of
    the file writes the edited run's frames byte for byte. A small sphere on group a's way is an
    obstacle to both: the speed0 edit keeps both groups' distance grids and routed paths, and moving
    group 1's target keeps both grids (the same meshes and reach) and group 0's route alone."""
    scene, proc, url = studio_on(args, tmp, "shot.json", {
        "time": {"frame_rate": 24, "frame_limit": 24}, "speed0": 12.0, "launch_rate": 800, "seed": 7,
        # a coarse grid, and detours (their navigation function: 0.8 s a build) for group a alone
        "obstacles": {"meshes": [{"mesh": "sphere.obj", "scale": 0.3}], "k_a": 1.0, "voxel": 0.5},
        "groups": [{"name": "a", "source": {"mesh": "cylinder.obj", "translate": [-15.0, 0.0, 0.0]},
                    "target": {"mesh": "sphere.obj", "translate": [15.0, 0.0, 0.0]}},
                   {"name": "b", "start": 0.5, "source": {"mesh": "sphere.obj", "translate": [-15.0, 12.0, 0.0]},
                    "target": {"mesh": "cylinder.obj", "translate": [15.0, 12.0, 0.0]}, "obstacles": {"detour_time": -1}}]})
    try:
        ws = WebSocket(url)
        ws.recv_json("hello")
        first = finished(ws)
        before = hashlib.sha256(ws.frame(first["frames"] - 1)[1][1]).hexdigest()
        e = error_of(ws, {"type": "set", "key": "groups.1.speed0", "value": -2})
        check("groups[1].speed0" in e and "out of range" in e, f"shot: an invalid group edit names the group's key: {e}")
        e = error_of(ws, {"type": "set", "key": "groups.0.target.mesh", "value": "/etc/passwd"})
        check("/etc/passwd" in e and "refused" in e, f"shot: a group's edit that names another file is refused: {e}")
        check(first["model_kept"] is False and first["groups_kept"] == 0 and first["grids_kept"] == 0
              and first["routes_kept"] == 0, "shot: the first run builds every group, its grids and routes")
        run = edited_run(ws, "groups.1.speed0", 7.0, first["generation"])
        check(run["stage"] == "finished", f"shot: a group's edit runs the shot again ({run['stage']} {run['failure']})")
        check(run["model_kept"] is True and run["groups_kept"] == 2,
              f"shot: a group's speed0 edit keeps every group's tets ({run['groups_kept']} kept, {run['build_seconds']:.3f} s)")
        check(run["grids_kept"] == 2 and run["routes_kept"] == 2,
              f"shot: ... and every group's obstacle grid ({run['grids_kept']}) and routed path ({run['routes_kept']})")
        after = hashlib.sha256(ws.frame(run["frames"] - 1)[1][1]).hexdigest()
        check(after != before, "shot: the edit changed the run (its groups come from the edited scene)")
        check_saved_run(args, ws, scene, run["frames"], os.path.join(tmp, "shot_out"), "shot (every group kept)")
        moved = edited_run(ws, "groups.1.target.translate", [16.0, 12.0, 0.0], run["generation"])
        check(moved["stage"] == "finished" and moved["model_kept"] is False and moved["groups_kept"] == 1,
              f"shot: moving group 1's target builds it again and keeps group 0 ({moved['groups_kept']} kept)")
        check(moved["grids_kept"] == 2 and moved["routes_kept"] == 1,
              f"shot: ... both grids kept ({moved['grids_kept']}), group 1's path routed again ({moved['routes_kept']} kept)")
        check_saved_run(args, ws, scene, moved["frames"], os.path.join(tmp, "shot_moved_out"), "shot (grids kept, a route made)")
        ws.close()
    finally:
        check_stopped(proc, "shot")


def check_flock_shot_keep(args, tmp):
    """A shape-flock shot whose second group starts from the first's formed shape: a group's speed0
    edit keeps both groups' samples and match; a new seed for the first group samples it again and
    so the second too (its source samples are the first's destinations), and `flockmorph run` of
    the saved file writes that run's frames byte for byte."""
    # a binds at about frame 60-70 (arrival steps quickly from 2 units): b flies the last frames
    scene, proc, url = studio_on(args, tmp, "flock_shot.json", {
        "mode": "shape_flock", "n": 120, "speed0": 20.0, "seed": 9, "time": {"frame_rate": 24, "frame_limit": 100},
        "shape_flock": {"arrival": {"time": 0.1, "radius": 2.0}},
        "groups": [{"name": "a", "source": {"mesh": "cylinder.obj", "translate": [-4.0, 0.0, 0.0]}, "target": {"mesh": "sphere.obj"}},
                   {"name": "b", "source": {"group": "a"}, "target": {"mesh": "cylinder.obj", "translate": [6.0, 0.0, 0.0]}}]})
    try:
        ws = WebSocket(url)
        ws.recv_json("hello")
        first = finished(ws)
        kept = edited_run(ws, "groups.1.speed0", 6.0, first["generation"])
        check(kept["stage"] == "finished" and kept["groups_kept"] == 2,
              f"shape-flock shot: a group's speed0 edit keeps both groups' samples ({kept['groups_kept']} kept)")
        seeded = edited_run(ws, "groups.0.seed", 10, kept["generation"])
        check(seeded["stage"] == "finished" and seeded["groups_kept"] == 0,
              f"shape-flock shot: a new seed for the first group samples both again ({seeded['groups_kept']} kept)")
        check_saved_run(args, ws, scene, seeded["frames"], os.path.join(tmp, "flock_shot_out"), "shape-flock shot")
        with open(os.path.join(tmp, "flock_shot_out", "stats.json")) as f:
            b = json.load(f)["groups"][1]
        check(b["start_time"] is not None and b["start_time"] < 96 / 24,
              f"shape-flock shot: the second group flies in the frames compared (starts at {b['start_time']} s)")
        ws.close()
    finally:
        check_stopped(proc, "shape-flock shot")


def check_playback(args, cache):
    """A played cache: its facts in hello, its frames as the reader decodes them, no edits."""
    proc, url = start_studio(args.cli, cache)
    try:
        ws = WebSocket(url)
        hello = ws.recv_json("hello")
        facts = json.loads(subprocess.run([sys.executable, os.path.join(HERE, "cache_facts.py"), cache],
                                          capture_output=True, text=True, check=True).stdout)
        check(hello["mode"] == "playback" and hello["cache"]["frames"] == facts["frames"]
              and hello["cache"]["stats"]["frames"] == facts["frames"], "playback: hello has the cache's facts and stats.json's")
        k = facts["frames"] // 2
        check(hashlib.sha256(ws.frame(k)[1][1]).hexdigest() == facts["sha256"][k], f"playback: frame {k} is the reader's")
        e = error_of(ws, {"type": "set", "key": "speed0", "value": 3})
        check("no scene" in e, f"playback: an edit is refused: {e}")
        e = error_of(ws, {"type": "frame", "k": facts["frames"]})
        check("not in the cache" in e, f"playback: a frame past the end: {e}")
        e = error_of(ws, {"type": "render"})
        check("no scene" in e, f"playback: Render is refused: {e}")
        ws.close()
    finally:
        code, err = stop_studio(proc)
    check(code == 0 and "AddressSanitizer" not in err, "playback: the studio exits 0, no sanitizer report")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cli", required=True)
    ap.add_argument("--source", required=True)
    ap.add_argument("--tmp", required=True)
    args = ap.parse_args()
    tmp = os.path.join(args.tmp, "studio_server")
    shutil.rmtree(tmp, ignore_errors=True)
    os.makedirs(tmp)
    scene = os.path.join(tmp, "scene.json")
    shutil.copy(os.path.join(args.source, "tests", "studio", "scene_small.json"), scene)
    for m in ("cylinder.obj", "sphere.obj"):
        shutil.copy(os.path.join(args.source, "examples", "flock_cylinder_sphere", m), tmp)
    t0 = time.time()
    args.render = os.path.join(tmp, "render")
    proc, url = start_studio(args.cli, scene, "--output", args.render)
    try:
        token, port = url.split("/")[3], int(url.split(":")[2].split("/")[0])
        check_http(url, port, token)
        check_refusals(url)
        ws = WebSocket(url)
        check(ws.recv_json("hello")["mode"] == "live", "hello says live")
        first = finished(ws)
        check(first["stage"] == "finished" and first["frames"] > 10, f"the first run finished ({first['frames']} frames)")
        check_bad_messages(ws)
        check_failed_run(url)
        check_model_keep(url)
        check_unrun_edits(url)
        check_burst(url)
        speed = check_two_editors(url, ws)
        check_vanishing_clients(url)
        check(proc.poll() is None, "the studio is still running")
        ws.close()
        ws = WebSocket(url)
        ws.recv_json("hello")
        check_truth(args, ws, scene, tmp)
        with open(scene) as f:
            doc = json.load(f)
        check(doc["speed0"] == speed and doc["launch_rate"] == 900, "the saved scene holds the last edits")
        ws.close()
    finally:
        code, err = stop_studio(proc)
    check_playback(args, os.path.join(tmp, "out", "frames.fmc"))
    check_flock_keep(args, tmp)
    check_cancelled_build(args, tmp)
    check_shot_edit(args, tmp)
    check_flock_shot_keep(args, tmp)
    check(code == 0, f"the studio exits 0 on SIGTERM ({code})")
    check("AddressSanitizer" not in err and "runtime error" not in err, "no sanitizer report")
    print(f"test_studio_server: {time.time() - t0:.1f} s")
    if FAILURES:
        print(f"test_studio_server: {len(FAILURES)} FAILED", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
