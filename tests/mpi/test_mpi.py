#!/usr/bin/env python3
"""The MPI scale-out (docs/scale-out.md) through mpirun and the flockmorph CLI.

- the same cache bytes, and the same stats.json but for timings and the rank count, as the plain
  run (no mpirun) for P = 1, 2, 3, 4 ranks of one thread and 2 ranks of two, on castling (with
  obstacles, curl noise and MDE), on words (3 ranks) and on a shape flock (tests/data/mpi/flock_stress.json:
  boids, a deforming target, the vortex, an obstacle, R over the run, stepped homing, floating);
- a stress case: on 4 ranks every agent changes rank (castling's flock, and the shape flock, sweep
  the slab axis), halos are exchanged, and the bytes still match;
- a travelling target (examples/flock_travel, target.path) gives the plain run's bytes on 2 and 3 ranks;
- shots (castling's king then rook; a chain of groups each starting from the previous one's
  shape; flock_sequence's sphere then torus) give the plain run's bytes on P ranks;
- a run interrupted on 2 ranks resumes on 3 with the uninterrupted plain run's bytes (both modes);
- checkpoints written by every rank at once (MPI-IO) at a planned stop (--stop-after-frame): the
  shape flock's holds the plain run's bytes (but for its timings) on 3 ranks; either mode's resumes
  on another P with the uninterrupted plain run's bytes; a full disk during one stops every rank
  with exit 3 and leaves no checkpoint, and so does a directory where the checkpoint goes;
- memory: on 4 ranks the largest rank peaks well below the one process, and the 4 ranks of one
  machine together (their summed Pss: one model, prepared by the machine's first rank; both modes)
  well below four processes (measured from outside); ranks counted as two machines give the same
  bytes (both modes);
- failure: a full disk on rank 0 (ulimit -f; both modes) stops every rank with exit 3 and a readable partial
  cache; SIGTERM to mpirun stops the run, nothing hangs; a rank killed with SIGKILL ends the job;
  ranks started on different jobs (an MPMD launch with another --set, --stop-after-frame, FM_
  variable or --resume on rank 1) stop with exit 1 naming what differs, before any work, and the
  checkpoint one rank was to resume from stays;
- threads: 3 ranks on one machine without --threads share its cores (stats.json's threads) and a
  short run stays short; --threads wins.

    test_mpi.py --cli build/flockmorph --mpiexec /usr/bin/mpiexec --source REPO --tmp DIR [--part PART] [CASES]
"""
import argparse
import collections
import hashlib
import json
import os
import resource
import shutil
import signal
import struct
import subprocess
import sys
import time
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "helpers"))
from octahedron import octahedron_obj  # noqa: E402

ARGS = None
fmc = None  # python/flockmorph_cache.py, imported from --source

# stats.json keys that may differ between runs of different P or T (docs/stats.md)
VARYING = {"preprocess_seconds", "simulate_seconds", "output_seconds", "agent_steps_per_second",
           "steps_per_second", "threads", "ranks", "scale_out", "command_line", "start_time", "machine", "cache",
           "cache_absolute", "working_directory"}


def env():
    e = dict(os.environ)
    if os.geteuid() == 0:  # Open MPI refuses root without both
        e["OMPI_ALLOW_RUN_AS_ROOT"] = "1"
        e["OMPI_ALLOW_RUN_AS_ROOT_CONFIRM"] = "1"
    e["OMPI_MCA_mpi_yield_when_idle"] = "1"  # oversubscribed ranks give the core back while they wait
    return e


def command(scene, out, ranks=None, threads=1, extra=(), machine_ranks=None):
    """machine_ranks=k: every k ranks count as one machine (FM_TEST_RANKS_PER_MACHINE), each with its
    own first rank that builds the model the machine's ranks share."""
    cmd = [ARGS.cli, "run", os.path.join(ARGS.source, scene), "-o", out, "--quiet", "--threads", str(threads),
           *extra]
    if ranks is not None:
        machines = ["-x", f"FM_TEST_RANKS_PER_MACHINE={machine_ranks}"] if machine_ranks else []
        cmd = [ARGS.mpiexec, "--oversubscribe", "-np", str(ranks), *machines] + cmd
    return cmd


def run(scene, name, ranks=None, threads=1, extra=(), timeout=600, preexec=None, machine_ranks=None):
    out = os.path.join(ARGS.tmp, "mpi_" + name)
    shutil.rmtree(out, ignore_errors=True)
    done = subprocess.run(command(scene, out, ranks, threads, extra, machine_ranks), stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, text=True, timeout=timeout, env=env(), preexec_fn=preexec)
    return done, out


def sha256(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def stats(out):
    with open(os.path.join(out, "stats.json")) as f:
        j = json.load(f)
    return {k: v for k, v in j.items() if k not in VARYING}


def pieces(agents):
    """Cache pieces of `agents` agents (output.piece_agents): the ranks then write the frames in
    parallel, each encoding the pieces of its share (docs/scale-out.md)."""
    return ("--set", f"output.piece_agents={agents}")


PLAIN_RUNS = {}  # (scene, extra) -> the plain run's (cache digest, stats.json without VARYING)


def plain_run(case, scene, extra=()):
    """The plain run (no mpirun, 2 threads) of `scene` with `extra`, as (the cache's SHA-256,
    stats(out)). Many cases compare their ranks with the same plain run (castling's rook in pieces of
    1000 seven times): it runs once for the whole file, since its bytes are the same for any thread
    count and any run (test_examples and test_example_caches check that)."""
    key = (scene, tuple(extra))
    if key not in PLAIN_RUNS:
        done, out = run(scene, "plain", threads=2, extra=extra)
        case.assertEqual(done.returncode, 0, done.stderr)
        PLAIN_RUNS[key] = (sha256(os.path.join(out, "frames.fmc")), stats(out))
    return PLAIN_RUNS[key]


class SameBytes(unittest.TestCase):
    def check_scene(self, scene, runs, extra=(), machine_ranks=None):
        """Returns each run's stats.json, by (ranks, threads)."""
        want, want_stats = plain_run(self, scene, extra)
        every = {}
        for ranks, threads in runs:
            done, got = run(scene, f"p{ranks}t{threads}", ranks, threads, extra, machine_ranks=machine_ranks)
            self.assertEqual(done.returncode, 0, f"{scene} on {ranks} ranks: {done.stderr}")
            self.assertEqual(sha256(os.path.join(got, "frames.fmc")), want,
                             f"{scene}: the cache of {ranks} ranks x {threads} threads differs from the plain run's")
            self.assertEqual(stats(got), want_stats, f"{scene}: stats.json of {ranks} ranks differs")
            with open(os.path.join(got, "stats.json")) as f:
                j = json.load(f)
            self.assertEqual(j["ranks"], ranks)
            if ranks > 1:
                self.assertGreater(j["scale_out"]["bytes_sent_per_agent_step"], 0)
            every[(ranks, threads)] = j
        return every

    def test_castling(self):
        """9038 agents in pieces of 1000: every rank encodes its share of each frame. And a stress
        case: castling's flock sweeps along the slab axis from the source to the target, so on 4
        ranks every agent is handed on at least once, halos carry MDE neighbours, the bytes still
        match."""
        # 3 ranks, the odd split, run in test_castling_on_two_machines (as 2 + 1 and 1 + 1 + 1 machines)
        every = self.check_scene("examples/castling/rook.json", [(1, 1), (2, 1), (4, 1), (2, 2)], pieces(1000))
        j = every[(4, 1)]
        s = j["scale_out"]
        self.assertGreaterEqual(s["migrations"], j["agents"], s)
        self.assertGreater(s["halo_agents_per_agent_step"], 0, s)
        self.assertLess(s["load_imbalance"], 2.0, s)  # rebalanced: not all on one rank
        self.assertGreaterEqual(s["busy_imbalance"], 1.0, s)  # the busiest rank's work over the mean
        self.assertLessEqual(s["busy_imbalance"], 4.0, s)

    def test_castling_on_two_machines(self):
        """Ranks 0-1 and 2-3 as two machines: each machine's first rank builds the model and its
        ranks share it (docs/scale-out.md, "One model a machine"); and every rank its own machine,
        each building and holding its model alone."""
        self.check_scene("examples/castling/rook.json", [(4, 1), (3, 1)], pieces(1000), machine_ranks=2)
        self.check_scene("examples/castling/rook.json", [(3, 1)], pieces(1000), machine_ranks=1)

    def test_shape_flock_on_two_machines(self):
        """The shape flock's model shared per machine (its destinations on the deforming target, the
        agents' parameters); the other ranks build the target's deformation, the path and the
        obstacle's grid themselves."""
        self.check_scene(FLOCK_STRESS, [(4, 1), (3, 1)], pieces(1024), machine_ranks=2)

    def test_castling_one_piece(self):
        """The default pieces (65536 agents): rank 0 encodes the one piece, the other two shares are
        empty. Every frame is laid out in the same pieces, so the first 60 (agents launched and
        flying) show the layout as the whole run did (test_castling runs it whole)."""
        self.check_scene("examples/castling/rook.json", [(3, 1)], SHORT_ROOK)

    def test_more_ranks_than_pieces(self):
        """Two pieces on three ranks: a share may hold no piece (first 60 frames, as above)."""
        self.check_scene("examples/castling/rook.json", [(3, 1)], pieces(5000) + SHORT_ROOK)

    def test_words(self):
        """The largest tetra example (13,818 tets), on the odd split; 2 and 4 ranks are castling's."""
        self.check_scene("examples/words/scene.json", [(3, 1)], pieces(2000))

    def test_moving_target(self):
        """A target that breathes and walks off (target_motion, issue 38): a function of time alone,
        its binding built by every rank from the target tets (on two machines, from the machine's
        shared ones); 40 frames of motion after the flock formed."""
        extra = pieces(4096) + ("--set", "time.frame_limit=160")
        # one run on 3 ranks as two machines (ranks 0-1 and 2): the CI's time is short, and 2 and 3
        # ranks of one machine are what every other SameBytes case checks
        self.check_scene("examples/walking_suzanne/scene.json", [(3, 1)], extra, machine_ranks=2)

    def test_castling_shot(self):
        """The whole castling (groups king, then rook): every group's state on P ranks, each rank
        encoding its share of the rows (pieces of 2000 agents; the default's one piece: one rank
        encodes the frame the others send it)."""
        self.check_scene("examples/castling/scene.json", [(3, 1)], pieces(2000))
        self.check_scene("examples/castling/scene.json", [(2, 1)])

    def test_shot_chain(self):
        """Groups starting from the previous one's formed shape (a -> b -> c): every rank knows the
        rows (and vertex orders) taken over from the agents of every rank, and sends each of its
        agents' tets to the rank whose share holds its row; the agents still waiting come from the
        model on the rank of their row."""
        # 4 ranks run below as two machines; one rank under mpirun is castling's and the flock's
        self.check_scene("tests/data/mpi/shot_chain.json", [(2, 1), (3, 1), (2, 2)], pieces(1000))
        self.check_scene("tests/data/mpi/shot_chain.json", [(3, 1)])
        # two "machines": each first rank builds every group, b from a's target tets, which only it keeps
        self.check_scene("tests/data/mpi/shot_chain.json", [(4, 1)], pieces(1000), machine_ranks=2)

    def test_shape_flock_shot(self):
        """A sphere that becomes a torus (flock_sequence: the torus group takes over the sphere's
        bound agents, the same rows), the ranks encoding their shares of the rows."""
        self.check_scene("examples/flock_sequence/scene.json", [(3, 1)], pieces(1000))
        self.check_scene("examples/flock_sequence/scene.json", [(2, 1)])
        self.check_scene("examples/flock_sequence/scene.json", [(3, 1)], pieces(1000), machine_ranks=2)

    def test_shape_flock_gathered(self):
        """Pieces that are not whole blocks of 1024 agents (the flock measures' blocks): rank 0
        gathers every frame, writes and measures it (2 ranks gather as 3 do)."""
        self.check_scene(FLOCK_STRESS, [(3, 1)], pieces(1000))

    def test_travelling_target(self):
        """examples/flock_travel: the bird, then its bound agents, carried along its route
        (target.path): each rank evaluates the same target at the same times; frames written in
        parallel (pieces of 1024) and gathered."""
        # to frame 300: 3.5 s of the route after the bird formed (it sets off at 9 s, frame 216)
        self.check_scene("examples/flock_travel/scene.json", [(3, 1)], pieces(1000) + ("--set", "time.frame_limit=300"))

    def test_flock_routed_round_an_obstacle(self):
        """A wall across the shape flock's straight path (obstacles.route, issue 38): the first rank of
        each machine routes R and hands the margin on, so every rank flies the same rerouted path."""
        # ranks 0-1 share their machine's route, rank 2 routes alone
        self.check_scene("tests/flock/route/wall.json", [(3, 1)], pieces(512), machine_ranks=2)

    def test_shape_flock(self):
        """The flock flies from x = -15 to x = 10 along the slab axis: on 4 ranks the agents are
        handed on (about once an agent: the rebalanced slabs move with the flock, so the count
        depends on its shape; 2,927 for 3,000 agents with issue 37's looser flock, a little more
        before), and the boids read ghosts. Pieces of 1024 agents: the ranks write the frames in
        parallel and sum the measures from their shares."""
        # 3 ranks, the odd split: test_shape_flock_on_two_machines (pieces of 1024) and test_shape_flock_gathered
        every = self.check_scene(FLOCK_STRESS, [(1, 1), (2, 1), (4, 1), (2, 2)], pieces(1024))
        s = every[(4, 1)]["scale_out"]
        self.assertGreaterEqual(s["migrations"], every[(4, 1)]["agents"] // 2, s)
        self.assertGreater(s["halo_agents_per_agent_step"], 0, s)
        self.assertLess(s["load_imbalance"], 2.0, s)
        self.assertGreaterEqual(s["busy_imbalance"], 1.0, s)


def peak_rss(cmd):
    """The largest resident memory, in bytes, of any process `cmd` starts (under mpirun: the largest
    rank), measured from outside the engine: a child Python runs it and reads RUSAGE_CHILDREN, which
    takes the peak of every process it and its children waited for. Returns (completed, bytes)."""
    probe = ("import resource, subprocess, sys\n"
             "r = subprocess.run(sys.argv[1:], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)\n"
             "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024)\n"
             "sys.stdout.write(r.stdout)\n"
             "sys.stderr.write(r.stderr)\n"
             "sys.exit(r.returncode)\n")
    done = subprocess.run([sys.executable, "-c", probe, *cmd], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          text=True, timeout=600, env=env())
    return done, int((done.stdout.split() or ["0"])[0])


def machine_peak(cmd):
    """The most memory the flockmorph processes that `cmd` starts use together, in bytes, measured
    from outside the engine by tools/machine-memory.py: the peak of their summed proportional set
    sizes (Pss counts a page that several ranks map once, split among them). Returns (completed,
    bytes)."""
    tool = os.path.join(ARGS.source, "tools", "machine-memory.py")
    done = subprocess.run([sys.executable, tool, *cmd], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          timeout=600, env=env())
    return done, summed_pss(done.stdout)


def summed_pss(report):
    """The summed Pss peak, in bytes, from tools/machine-memory.py's report (0 when it has none)."""
    peak = [word.split("=")[1] for word in report.split() if word.startswith("sum_pss_peak_MiB=")]
    return int(peak[0]) * 2**20 if peak else 0


def both_peaks(cmd):
    """peak_rss and machine_peak of one run: tools/machine-memory.py run under peak_rss's probe (the
    tool's own Python is far smaller than a rank). Returns (completed, (largest RSS, summed Pss))."""
    done, largest = peak_rss([sys.executable, os.path.join(ARGS.source, "tools", "machine-memory.py"), *cmd])
    return done, (largest, summed_pss(done.stdout))


ROOK_PEAKS = {}  # castling's rook at 3·10^5 agents: the peaks of one process and of 4 ranks, measured once


class Memory(unittest.TestCase):
    def test_a_machine_holds_one_model(self):
        """castling's rook at 3·10^5 agents on 4 ranks of one machine: only the machine's first rank
        prepares the model (TetGen, the preparation's peak of 284 bytes an agent) and the 4 ranks
        share its arrays (132 bytes an agent), so the machine's memory (the ranks' summed Pss)
        peaks well below four processes' worth. It measured 1.54 times the one process (1.99 when
        every rank built its own model); the bytes are the plain run's."""
        (_, alone), (_, machine) = self.rook_peaks()
        self.assertLess(machine, 1.75 * alone,
                        f"4 ranks together {machine / 2**20:.0f} MiB, one process {alone / 2**20:.0f} MiB")

    def test_a_rank_holds_its_share(self):
        """castling's rook at 3·10^5 agents, all launched at once: each of 4 ranks holds its slab's
        agents and its share of the frame, so the largest rank peaks well below the one process
        (docs/limits.md, "On P ranks"), measured from outside; the same bytes; and stats.json's
        max_rank_peak_rss_bytes is that peak."""
        (alone, _), (ranks, _) = self.rook_peaks()
        four = os.path.join(ARGS.tmp, "mem4")
        self.assertLess(ranks, 0.8 * alone, f"largest of 4 ranks {ranks / 2**20:.0f} MiB, one process {alone / 2**20:.0f} MiB")
        with open(os.path.join(four, "stats.json")) as f:
            reported = json.load(f)["scale_out"]["max_rank_peak_rss_bytes"]
        self.assertGreater(reported, 0.9 * ranks)  # mpirun's own peak is far below a rank's
        self.assertLessEqual(reported, ranks)

    def rook_peaks(self):
        """The two cases above measure the same runs (castling's rook at 3·10^5 agents, all launched at
        once, on one process and on 4 ranks of one machine): run once, for both, each measure taken
        from outside as before. Returns ((largest RSS, summed Pss) of the one process, of the 4 ranks)."""
        if not ROOK_PEAKS:
            sets = ("--set", "n=300000", "--set", "launch_rate=1e9", "--set", "time.frame_limit=4") + pieces(16384)
            ROOK_PEAKS["peaks"] = self.one_and_four("examples/castling/rook.json", "mem", sets, both_peaks)
        return ROOK_PEAKS["peaks"]

    def one_and_four(self, scene, name, sets, measure=peak_rss):
        """(one process's peak, 4 ranks' peak) as `measure` takes them (peak_rss: the largest rank's;
        machine_peak: the ranks' together), the caches checked to be the same."""
        one, four = os.path.join(ARGS.tmp, name + "1"), os.path.join(ARGS.tmp, name + "4")
        for out in (one, four):
            shutil.rmtree(out, ignore_errors=True)
        done, alone = measure(command(scene, one, None, 1, sets))
        self.assertEqual(done.returncode, 0, done.stderr)
        done, ranks = measure(command(scene, four, 4, 1, sets))
        self.assertEqual(done.returncode, 0, done.stderr)
        self.assertEqual(sha256(os.path.join(four, "frames.fmc")), sha256(os.path.join(one, "frames.fmc")))
        return alone, ranks

    def test_a_shot_rank_holds_its_share(self):
        """castling's shot (king, then rook) at 1.5·10^5 agents a group: each group's store is made
        as the rank's share and each rank encodes its share of the rows, so the largest of 4 ranks
        peaks well below the one process (it measured 0.57 of it; 0.86 when every group's store was
        made whole and rank 0 assembled and wrote every frame)."""
        sets = ("--set", "n=150000", "--set", "groups.0.launch_rate=1e9", "--set", "groups.1.launch_rate=1e9",
                "--set", "time.frame_limit=4") + pieces(16384)  # each group sets its own launch_rate
        alone, ranks = self.one_and_four("examples/castling/scene.json", "shotmem", sets)
        self.assertLess(ranks, 0.7 * alone, f"largest of 4 ranks {ranks / 2**20:.0f} MiB, one process {alone / 2**20:.0f} MiB")

    def test_a_flock_rank_holds_its_slab(self):
        """flock_suzanne_torus at 3·10^5 agents (random sampling, whose preparation is small): each
        of 4 ranks holds its slab's agents and its halo in its store and grid, and its share of the
        frame, so the largest rank peaks well below the one process (0.68 of it measured; 0.83 when
        every rank held the whole store; the rest is mostly the preparation and the libraries)."""
        sets = ("--set", "n=300000", "--set", "shape_flock.sampling=random", "--set", "time.frame_limit=4") + pieces(16384)
        alone, ranks = self.one_and_four("examples/flock_suzanne_torus/scene.json", "flockmem", sets)
        self.assertLess(ranks, 0.75 * alone, f"largest of 4 ranks {ranks / 2**20:.0f} MiB, one process {alone / 2**20:.0f} MiB")

    def test_a_flock_machine_holds_one_model(self):
        """flock_suzanne_torus at 2·10^5 agents, stratified sampling (its preparation peaks at about
        440 bytes an agent): only the machine's first rank samples, and the 4 ranks share its model
        (100 bytes an agent), so together they peak well below four processes' worth: 1.76 times
        the one process measured (2.96 when every rank sampled and held its own model)."""
        sets = ("--set", "n=200000", "--set", "time.frame_limit=4") + pieces(16384)
        alone, machine = self.one_and_four("examples/flock_suzanne_torus/scene.json", "flockpss", sets, machine_peak)
        self.assertLess(machine, 2.2 * alone,
                        f"4 ranks together {machine / 2**20:.0f} MiB, one process {alone / 2**20:.0f} MiB")

    def test_a_flock_shot_rank_holds_its_slab(self):
        """flock_sequence at 2·10^5 agents: each group's store is the rank's slab's and no rank
        holds a whole frame or the cache writer's frame buffers, so the largest rank peaks below the
        one process (0.69 of it measured; 0.90 when every rank held every group's whole store;
        rank 0 peaked at 1.13 of it when it also assembled and wrote every frame)."""
        sets = ("--set", "n=200000", "--set", "time.frame_limit=4") + pieces(16384)
        alone, ranks = self.one_and_four("examples/flock_sequence/scene.json", "flockshotmem", sets)
        self.assertLess(ranks, 0.8 * alone, f"largest of 4 ranks {ranks / 2**20:.0f} MiB, one process {alone / 2**20:.0f} MiB")


def frames_in(path):
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a cut-short cache reads with a warning
        return fmc.open(path).frames


LONG_SCENE, LONG_SETS = "examples/castling/rook.json", ("--set", "n=60000") + pieces(4096)  # about 20 s on two cores
# The interrupted-and-resumed cases run their scene twice whole (the resumed run and the plain one):
# at 30000 rook agents and 20000 flock agents, not 60000 and 30000 (3.5 and 4 minutes of a loaded
# CI), they still run long enough to be stopped by a signal after their first checkpoint (every 5
# frames), well before their end: the rook launches for 7.5 s of its time (180 frames), the flock
# flies its 100 frames; and the flock's cache outgrows the disk-full case's 8 MiB limit.
RESUMED_SETS = ("--set", "n=30000") + pieces(4096)
FLOCK_STRESS = "tests/data/mpi/flock_stress.json"
SHORT_ROOK = ("--set", "time.frame_limit=60")  # castling's rook launched and flying (all launched by frame 54)
LONG_FLOCK_SETS = ("--set", "n=20000") + pieces(4096)


def checkpoint_header(path):
    """The checkpoint's header (docs/resume.md): version, agents, frames, pieces, statistics bytes."""
    with open(path, "rb") as f:
        magic, version, _, _, _, agents, frames, _, pieces_, stats_bytes = struct.unpack("<8sII7Q", f.read(72))
    assert magic == b"FMCHKPT\0", path
    return {"version": version, "agents": agents, "frames": frames, "pieces": pieces_, "stats_bytes": stats_bytes}


class Segments(unittest.TestCase):
    """A run split at a planned stop (--stop-after-frame): every rank writes its agents' part of the
    checkpoint at once (MPI-IO), rank 0 the rest; any P resumes it."""

    def segment(self, scene, name, ranks, sets, stop=None, resume=False, fresh=True):
        out = os.path.join(ARGS.tmp, "mpi_" + name)
        if fresh:
            shutil.rmtree(out, ignore_errors=True)
        extra = sets + (("--stop-after-frame", str(stop)) if stop is not None else ()) + (("--resume",) if resume else ())
        done = subprocess.run(command(scene, out, ranks, 1, extra), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True, timeout=600, env=env())
        self.assertEqual(done.returncode, 0, f"{name}: {done.stderr}")
        return out

    def across_ranks(self, scene, name, sets, stop, first, then):
        """Stops on `first` ranks (None: no mpirun), resumes on `then`: the uninterrupted plain bytes."""
        out = self.segment(scene, name, first, sets, stop)
        self.assertTrue(os.path.exists(os.path.join(out, "checkpoint.fmck")))
        self.assertEqual(frames_in(os.path.join(out, "frames.fmc.partial")), stop + 1)
        self.segment(scene, name, then, sets, resume=True, fresh=False)
        whole, whole_stats = plain_run(self, scene, sets)
        self.assertEqual(sha256(os.path.join(out, "frames.fmc")), whole, name)
        self.assertEqual(stats(out)["frames"], whole_stats["frames"])
        # the look's history travels in the checkpoint: a resumed run measures what the plain one did
        self.assertEqual(stats(out).get("flock_measures_per_frame"), whole_stats.get("flock_measures_per_frame"))
        self.assertFalse(os.path.exists(os.path.join(out, "checkpoint.fmck")))

    def test_shape_flock_checkpoint_is_the_plain_runs(self):
        """The flock's checkpoint is laid out by agent id: written by 3 ranks (each the agents of its
        share of the 1024-agent pieces) it holds the plain run's bytes, but for the timings (the
        first two doubles of the statistics) and so the trailer's checksum."""
        sets = pieces(1024)
        one = self.segment(FLOCK_STRESS, "ckpt_flock_plain", None, sets, 12)
        three = self.segment(FLOCK_STRESS, "ckpt_flock_p3", 3, sets, 12)
        with open(os.path.join(one, "checkpoint.fmck"), "rb") as f:
            a = f.read()
        with open(os.path.join(three, "checkpoint.fmck"), "rb") as f:
            b = f.read()
        h = checkpoint_header(os.path.join(three, "checkpoint.fmck"))
        self.assertEqual((h["version"], h["frames"]), (4, 13))
        self.assertEqual(h["pieces"], (h["agents"] + 1023) // 1024)
        self.assertGreaterEqual(h["pieces"], 3)  # every rank wrote one at least
        self.assertEqual(len(a), len(b))
        self.assertEqual(a[:72], b[:72])
        self.assertEqual(a[72 + 16:-8], b[72 + 16:-8])

    def test_shape_flock_stopped_on_3_resumed_on_1(self):
        self.across_ranks(FLOCK_STRESS, "seg_flock_3_1", pieces(1024), 12, 3, None)

    def test_shape_flock_stopped_on_1_resumed_on_2(self):
        self.across_ranks(FLOCK_STRESS, "seg_flock_1_2", pieces(1024), 12, None, 2)

    def test_tetra_stopped_on_3_resumed_on_1(self):
        """The tetra morph's checkpoint lists the launched agents rank by rank, then the waiting
        ones in id order, each rank writing a share of those."""
        self.across_ranks("examples/castling/rook.json", "seg_tetra_3_1", pieces(1000), 20, 3, None)

    def test_tetra_stopped_on_1_resumed_on_2(self):
        self.across_ranks("examples/castling/rook.json", "seg_tetra_1_2", pieces(1000), 20, None, 2)

    def test_tetra_with_arrivals_stopped_on_1_resumed_on_3(self):
        """Stopped once agents arrived (the one process's file holds them first, before the last
        re-sort: rank 0's share of the slots all of them, rank 2's some): each rank reads its share
        and the launched agents go to their slabs' ranks; the plain run's bytes."""
        self.across_ranks("examples/castling/rook.json", "seg_tetra_arrived_1_3", pieces(1000), 160, None, 3)

    def shot_across_ranks(self, scene, name, stop, first, then):
        """A shot: the group files beside the checkpoint after the stop, none left at the end."""
        self.across_ranks(scene, name, pieces(1000), stop, first, then)
        out = os.path.join(ARGS.tmp, "mpi_" + name)
        self.assertEqual([f for f in os.listdir(out) if f.startswith("checkpoint")], [], name)

    def test_tetra_shot_stopped_on_3_resumed_on_2(self):
        """A shot's checkpoint is the shot's file (its clock, its groups' measures) and every group's
        store, each written by every rank at once. Stopped after group b took over a's rows: on
        resume every rank learns the rows again from a's agents of every rank."""
        self.shot_across_ranks("tests/data/mpi/shot_chain.json", "seg_shot_3_2", 150, 3, 2)

    def test_tetra_shot_stopped_on_1_resumed_on_3(self):
        """Stopped after c took over b's rows, which b took over from a's."""
        self.shot_across_ranks("tests/data/mpi/shot_chain.json", "seg_shot_1_3", 200, None, 3)

    def test_shape_flock_shot_stopped_on_2_resumed_on_1(self):
        """flock_sequence stopped while the torus flies (it took over the sphere's bound agents)."""
        self.shot_across_ranks("examples/flock_sequence/scene.json", "seg_flock_shot_2_1", 200, 2, None)

    def test_checkpoint_disk_full(self):
        """Frame 0's cache fits under the 8 MiB limit, the checkpoint of 140 000 agents (10 MB) does
        not: every rank stops with exit 3, no checkpoint (or .partial) is left, the frame is. The
        model's shared memory (18.5 MB) does not fit under the limit either: the ranks say so and
        each builds its own model instead (until 2026-12-05 the ranks hung in
        MPI_Win_allocate_shared here)."""
        limit = 8 << 20

        def small_files():
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
        sets = ("--set", "n=140000") + pieces(4096) + ("--stop-after-frame", "0")
        done, out = run("examples/castling/rook.json", "ckpt_full", 2, extra=sets, timeout=300, preexec=small_files)
        self.assertEqual(done.returncode, 3, done.stderr)
        self.assertIn("checkpoint.fmck", done.stderr)
        self.assertIn("the file-size limit, ulimit -f); every rank builds its own model instead", done.stderr)
        self.assertFalse(os.path.exists(os.path.join(out, "checkpoint.fmck")))
        self.assertFalse(os.path.exists(os.path.join(out, "checkpoint.fmck.partial")))
        self.assertEqual(frames_in(os.path.join(out, "frames.fmc.partial")), 1)


    def test_directory_where_the_checkpoint_goes(self):
        """A directory named checkpoint.fmck.partial (not empty) where the ranks would write: every
        rank stops with exit 3 and the errno text, and the directory is left as it was."""
        out = os.path.join(ARGS.tmp, "mpi_ckpt_dir")
        shutil.rmtree(out, ignore_errors=True)
        os.makedirs(os.path.join(out, "checkpoint.fmck.partial"))
        open(os.path.join(out, "checkpoint.fmck.partial", "keep"), "w").close()
        done = subprocess.run(command("examples/castling/rook.json", out, 2, 1, ("--stop-after-frame", "2")),
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=300, env=env())
        self.assertEqual(done.returncode, 3, done.stderr)
        self.assertIn("checkpoint.fmck': Is a directory", done.stderr)
        self.assertTrue(os.path.exists(os.path.join(out, "checkpoint.fmck.partial", "keep")))
        self.assertFalse(os.path.exists(os.path.join(out, "checkpoint.fmck")))


def tiny_scene(name, frames=30):
    """An octahedron's tets flying 20 units to its copy: a run of a second or two."""
    folder = os.path.join(ARGS.tmp, "mpi_scene_" + name)
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, "octahedron.obj"), "w") as f:
        f.write(octahedron_obj())
    scene = {"source": {"mesh": "octahedron.obj", "translate": [-10, 0, 0]},
             "target": {"mesh": "octahedron.obj", "translate": [10, 0, 0]}, "time": {"frame_limit": frames}}
    path = os.path.join(folder, "scene.json")
    with open(path, "w") as f:
        json.dump(scene, f)
    return path


def run_command(scene, out, extra=()):
    return [ARGS.cli, "run", scene, "-o", out, "--quiet", "--threads", "1", *extra]


def mpmd(first, second, timeout=60):
    """Rank 0 runs the command `first`, rank 1 `second` (an MPMD launch: each its own command line
    and environment)."""
    cmd = [ARGS.mpiexec, "--oversubscribe", "-n", "1", *first, ":", "-n", "1", *second]
    return subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=timeout, env=env())


class Failure(unittest.TestCase):
    def check_refused(self, done, out, *parts):
        """Ranks that run different jobs: exit 1 and one message naming rank 1 and what differs, and
        nothing written in the output directory but the lock and the empty folder."""
        self.assertEqual(done.returncode, 1, done.stderr)
        self.assertEqual(done.stderr.count("flockmorph: error:"), 1, done.stderr)
        self.assertIn("rank 1 of 2 does not run rank 0's job: ", done.stderr)
        for part in parts:
            self.assertIn(part, done.stderr)
        for name in ("frames.fmc", "frames.fmc.partial", "stats.json", "wedge.json"):
            self.assertFalse(os.path.exists(os.path.join(out, name)), name)

    def test_stale_shared_memory_removed(self):
        """A job killed while its machine's shared model still had a name in /dev/shm left the
        segment there (issue 42): the next job's first rank on the machine removes those whose
        process is gone, and leaves a live process's."""
        dead = subprocess.Popen(["true"])
        dead.wait()
        stale, live = f"/dev/shm/flockmorph.{dead.pid}.1", f"/dev/shm/flockmorph.{os.getpid()}.1"
        for path in (stale, live):
            with open(path, "wb") as f:
                f.write(b"left")
        try:
            done, _ = run(tiny_scene("stale_shm"), "stale_shm", ranks=2)
            self.assertEqual(done.returncode, 0, done.stderr)
            self.assertFalse(os.path.exists(stale), "a dead job's segment is still there")
            self.assertTrue(os.path.exists(live), "a live process's segment was removed")
        finally:
            for path in (stale, live):
                if os.path.exists(path):
                    os.remove(path)

    def test_ranks_with_different_overrides(self):
        """An MPMD launch whose second rank has another --set: refused before any work (exit 1),
        naming the scene and both ranks' arguments, where the cache was a mix of the two."""
        scene, out = tiny_scene("sets"), os.path.join(ARGS.tmp, "mpi_sets")
        shutil.rmtree(out, ignore_errors=True)
        done = mpmd(run_command(scene, out, ("--set", "speed0=10")), run_command(scene, out, ("--set", "speed0=11")))
        self.check_refused(done, out, "the scene as loaded differs",
                           f"(rank 0: {scene} --set speed0=10; rank 1: {scene} --set speed0=11)")

    def test_ranks_with_different_options(self):
        scene, out = tiny_scene("options"), os.path.join(ARGS.tmp, "mpi_options")
        shutil.rmtree(out, ignore_errors=True)
        done = mpmd(run_command(scene, out), run_command(scene, out, ("--stop-after-frame", "3")))
        self.check_refused(done, out, "--stop-after-frame differs (rank 0: not given; rank 1: 3)")

    def test_ranks_with_different_environment(self):
        """An FM_ variable only rank 1 has (mpirun's -x in its part of the launch)."""
        scene, out = tiny_scene("environment"), os.path.join(ARGS.tmp, "mpi_environment")
        shutil.rmtree(out, ignore_errors=True)
        done = mpmd(run_command(scene, out), ["-x", "FM_JOB_NOTE=b"] + run_command(scene, out))
        self.check_refused(done, out, "the environment variable FM_JOB_NOTE differs (rank 0: unset; rank 1: b)")

    def test_rank_resuming_alone_keeps_the_checkpoint(self):
        """Rank 1 alone asks to --resume: refused with exit 1 before rank 0, starting over, would
        delete the checkpoint (and the partial cache) that the run is to resume from."""
        scene, out = tiny_scene("resume"), os.path.join(ARGS.tmp, "mpi_resume_alone")
        shutil.rmtree(out, ignore_errors=True)
        stopped = subprocess.run(run_command(scene, out, ("--stop-after-frame", "3")), stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True, timeout=60)
        self.assertEqual(stopped.returncode, 0, stopped.stderr)
        checkpoint = os.path.join(out, "checkpoint.fmck")
        before = sha256(checkpoint)
        done = mpmd(run_command(scene, out), run_command(scene, out, ("--resume",)))
        self.assertEqual(done.returncode, 1, done.stderr)
        self.assertIn("rank 1 of 2 does not run rank 0's job: --resume differs (rank 0: not given; rank 1: given)",
                      done.stderr)
        self.assertEqual(sha256(checkpoint), before)
        self.assertEqual(frames_in(os.path.join(out, "frames.fmc.partial")), 4)

    def test_bad_input_only_the_first_rank_meets(self):
        """n below TetGen's tet count is found while the model is built, which only each machine's
        first rank does (ranks 0 and 2 of two "machines"): every rank stops with exit 2 and the one
        message, nothing hangs waiting for the model."""
        done, out = run("examples/castling/rook.json", "bad_n", 3, extra=("--set", "n=10"), timeout=120,
                        machine_ranks=2)
        self.assertEqual(done.returncode, 2, done.stderr)
        self.assertEqual(done.stderr.count("flockmorph: error:"), 1, done.stderr)
        self.assertIn("n: 10 is smaller than the 9038 tets TetGen made", done.stderr)
        self.assertFalse(os.path.exists(os.path.join(out, "frames.fmc")))

    def test_too_many_agents_for_the_machine(self):
        """An n the machine cannot hold on 4 ranks is refused before TetGen, counting the model once
        for the machine: exit 2 and one message that says so (tests/world/test_memory.c checks the
        machine's estimate and the agents it says fit)."""
        physical = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        n = int(1.2 * physical / 800)  # 4 ranks need over 900 bytes an agent of n (one model of 132, four shares)
        if n > 5 * 10**8:  # past MDE's grid, which is refused first
            self.skipTest("this machine holds the largest n castling's MDE grid takes")
        done, _ = run("examples/castling/rook.json", "huge", 4, extra=("--set", f"n={n}"), timeout=120)
        self.assertEqual(done.returncode, 2, done.stderr)
        self.assertEqual(done.stderr.count("flockmorph: error:"), 1, done.stderr)
        self.assertIn("on this machine's 4 ranks (bytes per agent: the model 132, once;", done.stderr)
        self.assertIn("physical memory", done.stderr)

    def test_disk_full_on_rank_0(self):
        self.check_disk_full("examples/castling/rook.json", "full2", 8 << 20)  # castling's cache: about 45 MiB

    def test_shape_flock_disk_full_on_rank_0(self):
        self.check_disk_full(FLOCK_STRESS, "flock_full2", 8 << 20, LONG_FLOCK_SETS)  # its cache: about 60 MiB

    def check_disk_full(self, scene, name, limit, sets=()):
        """limit: at least 8 MiB, since Open MPI's own shared-memory files are made under it too."""
        def small_files():
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
        start = time.time()
        done, out = run(scene, name, 2, extra=sets, timeout=300, preexec=small_files)
        self.assertEqual(done.returncode, 3, done.stderr)  # I/O error, from every rank
        self.assertLess(time.time() - start, 300)
        self.assertFalse(os.path.exists(os.path.join(out, "frames.fmc")))
        partial = os.path.join(out, "frames.fmc.partial")
        self.assertTrue(os.path.exists(partial), os.listdir(out))
        self.assertGreater(frames_in(partial), 0)

    def start_long_run(self, name, extra=(), scene=LONG_SCENE, sets=LONG_SETS):
        out = os.path.join(ARGS.tmp, "mpi_" + name)
        shutil.rmtree(out, ignore_errors=True)
        cmd = command(scene, out, 2, 1, sets + tuple(extra))
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env())
        partial = os.path.join(out, "frames.fmc.partial")
        deadline = time.time() + 240
        while time.time() < deadline and proc.poll() is None:  # until frames are being written
            if os.path.exists(partial) and os.path.getsize(partial) > (1 << 20):
                break
            time.sleep(0.2)
        self.assertIsNone(proc.poll(), "the run ended before it could be interrupted")
        return proc, out

    def test_sigterm_stops_every_rank(self):
        proc, out = self.start_long_run("term2")
        proc.send_signal(signal.SIGTERM)
        try:
            _, err = proc.communicate(timeout=120)
        except subprocess.TimeoutExpired:
            proc.kill()
            self.fail("mpirun did not end within 120 s of SIGTERM")
        self.assertNotEqual(proc.returncode, 0)
        self.assertFalse(os.path.exists(os.path.join(out, "frames.fmc")))
        # every rank stopped at the same frame boundary: rank 0 said so, the frames so far read back
        self.assertIn("interrupted at frame", err)
        self.assertGreater(frames_in(os.path.join(out, "frames.fmc.partial")), 0)

    def interrupt_and_resume(self, name, scene, sets):
        """A checkpoint written on 2 ranks resumes on 3, and the cache is the uninterrupted plain
        run's, byte for byte (docs/resume.md)."""
        proc, out = self.start_long_run(name, ("--checkpoint-every", "5"), scene, sets)
        deadline = time.time() + 120
        while time.time() < deadline and not os.path.exists(os.path.join(out, "checkpoint.fmck")):
            time.sleep(0.2)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=120)
        self.assertIn("checkpoint written", err)
        resumed = subprocess.run(command(scene, out, 3, 1, sets + ("--resume",)), stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True, timeout=600, env=env())
        self.assertEqual(resumed.returncode, 0, resumed.stderr)
        plain, whole = run(scene, name + "_plain", threads=2, extra=sets)
        self.assertEqual(plain.returncode, 0, plain.stderr)
        self.assertEqual(sha256(os.path.join(out, "frames.fmc")), sha256(os.path.join(whole, "frames.fmc")))
        self.assertEqual(stats(out)["frames"], stats(whole)["frames"])

    def test_interrupted_on_2_resumed_on_3(self):
        self.interrupt_and_resume("resume", LONG_SCENE, RESUMED_SETS)

    def test_shape_flock_interrupted_on_2_resumed_on_3(self):
        self.interrupt_and_resume("flock_resume", FLOCK_STRESS, LONG_FLOCK_SETS)

    def test_killed_rank_ends_the_job(self):
        proc, out = self.start_long_run("kill2")
        ranks = subprocess.run(["pgrep", "-P", str(proc.pid)], stdout=subprocess.PIPE, text=True).stdout.split()
        self.assertTrue(ranks, "no rank processes under mpirun")
        os.kill(int(ranks[-1]), signal.SIGKILL)
        try:
            proc.communicate(timeout=120)
        except subprocess.TimeoutExpired:
            proc.kill()
            self.fail("mpirun did not end within 120 s of a rank's death")
        self.assertNotEqual(proc.returncode, 0)
        self.assertFalse(os.path.exists(os.path.join(out, "frames.fmc")))


class Threads(unittest.TestCase):
    def ranks_threads(self, name, ranks, extra=()):
        out = os.path.join(ARGS.tmp, "mpi_threads_" + name)
        shutil.rmtree(out, ignore_errors=True)
        cmd = [ARGS.mpiexec, "--oversubscribe", "-np", str(ranks), ARGS.cli, "run", tiny_scene("threads", frames=60),
               "-o", out, "--quiet", *extra]
        start = time.time()
        done = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=120, env=env())
        self.assertEqual(done.returncode, 0, done.stderr)
        with open(os.path.join(out, "stats.json")) as f:
            return json.load(f)["threads"], time.time() - start

    def test_ranks_share_the_cores(self):
        """3 ranks on this machine without --threads: each takes the cores / 3 (at least 1), not a
        thread per core each (6 threads on 2 cores took a minute for this run of a second); an
        explicit --threads still wins (2 ranks of 2 threads, 2 frames)."""
        threads, seconds = self.ranks_threads("default", 3)
        self.assertEqual(threads, max(1, os.cpu_count() // 3))
        self.assertLess(seconds, 30)
        threads, _ = self.ranks_threads("explicit", 2, ("--threads", "2", "--set", "time.frame_limit=2"))
        self.assertEqual(threads, 2)


def children_cpu():
    """CPU seconds (user and system) of the processes this one started and waited for, theirs included."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


class TimedResult(unittest.TextTestResult):
    """Prints each case's wall time and its processes' CPU time after its verdict, so that a CI log
    shows where test_mpi's minutes go; the CPU time does not grow with the machine's load as the wall
    time does (docs/testing.md)."""

    def startTest(self, test):
        self.started, self.cpu = time.monotonic(), children_cpu()
        super().startTest(test)

    def stopTest(self, test):
        super().stopTest(test)
        self.stream.writeln(f"    {time.monotonic() - self.started:.1f} s wall, {children_cpu() - self.cpu:.1f} s CPU"
                            f"  {test.id().split('.', 1)[1]}")
        self.stream.flush()


# The ctest tests that run this file side by side (tests/CMakeLists.txt: test_mpi_PART runs --part PART
# with a --tmp of its own), each about a third of its CPU time: beside the rest of the suite under
# ctest -j no one of them is near its timeout, as the whole file was (docs/testing.md). A part names
# classes, or cases of a class that is split; every case of the file is in exactly one part.
PARTS = {
    "tetra": tuple(f"SameBytes.test_{c}" for c in (
        "castling", "castling_on_two_machines", "castling_one_piece", "more_ranks_than_pieces", "words",
        "moving_target", "castling_shot", "shot_chain")),
    "flock": tuple(f"SameBytes.test_{c}" for c in (
        "shape_flock", "shape_flock_on_two_machines", "shape_flock_gathered", "shape_flock_shot",
        "travelling_target", "flock_routed_round_an_obstacle")) + ("Segments",),
    "failure": ("Failure", "Memory", "Threads"),
}


def case_ids(names):
    """The ids (module.Class.test_case) of the cases that unittest names `names` select."""
    module = sys.modules[__name__]
    suites = [unittest.defaultTestLoader.loadTestsFromName(n, module) for n in names]
    ids = []
    while suites:
        s = suites.pop()
        if isinstance(s, unittest.TestSuite):
            suites.extend(s)
        else:
            ids.append(s.id())
    return ids


def part_names(part, all_parts):
    """The unittest names of `part`, once every case of this file is known to be in exactly one part
    and `all_parts` (the parts the caller runs, comma-separated) to be PARTS, so that no case is left
    out of the suite and none runs twice."""
    placed = collections.Counter(i for names in PARTS.values() for i in case_ids(names))
    every = case_ids([n for n, c in globals().items() if isinstance(c, type) and issubclass(c, unittest.TestCase)])
    wrong = sorted(i for i in set(every) | set(placed) if placed[i] != 1)
    if wrong:
        sys.exit(f"test_mpi: PARTS does not place these cases exactly once: {', '.join(wrong)}")
    if all_parts is not None and sorted(all_parts.split(",")) != sorted(PARTS):
        sys.exit(f"test_mpi: the caller runs the parts {all_parts}, the file has {','.join(PARTS)}")
    return list(PARTS[part])


def main():
    global ARGS, fmc
    p = argparse.ArgumentParser()
    p.add_argument("--cli", required=True)
    p.add_argument("--mpiexec", required=True)
    p.add_argument("--source", required=True)
    p.add_argument("--tmp", required=True)
    p.add_argument("--part", choices=sorted(PARTS), help="run only this part's cases (PARTS)")
    p.add_argument("--all-parts", help="the parts the caller runs, comma-separated: checked to be PARTS")
    ARGS, rest = p.parse_known_args()
    if ARGS.part:
        if any(not r.startswith("-") for r in rest):
            p.error("--part runs its own cases: give either --part or the cases to run")
        rest = part_names(ARGS.part, ARGS.all_parts) + rest
    os.makedirs(ARGS.tmp, exist_ok=True)
    sys.path.insert(0, os.path.join(ARGS.source, "python"))
    import flockmorph_cache
    fmc = flockmorph_cache
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2,
                  testRunner=unittest.TextTestRunner(resultclass=TimedResult, verbosity=2))


if __name__ == "__main__":
    main()
