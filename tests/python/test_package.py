#!/usr/bin/env python3
"""Tests the Python reader as a package: `pip install ./python` as docs/cache-format.md gives it.

Makes a fresh virtual environment with Debian's interpreter and --system-site-packages (so Debian's
numpy, zstandard, setuptools and wheel are there and nothing comes from an index), installs a copy
of python/ with `pip install --no-build-isolation --no-index ./python`, then imports the module in
that environment from another directory and reads the committed format-2 fixture. Also checks that
the package's version is `flockmorph --version`'s, and that it uninstalls.

    test_package.py --cli build/flockmorph --tmp DIR --source REPO
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import unittest

ARGS = None

# Run inside the venv from another directory: what a user's script sees after the install.
PROBE = r"""
import importlib.metadata, json, os, sys
import numpy as np
import flockmorph_cache
with flockmorph_cache.open(sys.argv[1]) as cache:
    tets = cache.read_range("tet_vertices")
    out = {
        "file": os.path.realpath(flockmorph_cache.__file__),
        "prefix": os.path.realpath(sys.prefix),
        "version": flockmorph_cache.__version__,
        "metadata_version": importlib.metadata.version("flockmorph-cache"),
        "requires": importlib.metadata.requires("flockmorph-cache"),
        "len": len(cache),
        "times": cache.times().tolist(),
        "shape": list(tets.shape),
        "tets_ok": bool(np.array_equal(tets, (0.001 * np.arange(60) + np.arange(4)[:, None])
                                       .astype(np.float32).reshape(4, 5, 4, 3))),
        "phase": [f.phase.reshape(-1).tolist() for f in cache[1::2]],
    }
print(json.dumps(out))
"""


def run(cmd, cwd=None):
    """Runs cmd with the environment a user's shell would have, less what points Python or pip
    elsewhere (PYTHONPATH could import the source file instead of the installed one)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "PIP_", "VIRTUAL_ENV"))}
    env.update(PIP_NO_INPUT="1", PIP_DISABLE_PIP_VERSION_CHECK="1", PYTHONNOUSERSITE="1")
    done = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True)
    if done.returncode != 0:
        raise AssertionError(f"{' '.join(map(str, cmd))} (in {cwd}): exit {done.returncode}\n{done.stdout}")
    return done.stdout


class Package(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.root = os.path.join(ARGS.tmp, "py_package")
        shutil.rmtree(cls.root, ignore_errors=True)
        # pip builds in the project folder (build/, *.egg-info): build a copy, not the source tree
        cls.src = os.path.join(cls.root, "src")
        shutil.copytree(os.path.join(ARGS.source, "python"), os.path.join(cls.src, "python"),
                        ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
        cls.venv = os.path.join(cls.root, "venv")
        # Debian's interpreter runs this test (FM_PYTHON3); python3-venv gives it ensurepip
        run([sys.executable, "-m", "venv", "--system-site-packages", cls.venv])
        cls.python = os.path.join(cls.venv, "bin", "python")
        cls.pip = os.path.join(cls.venv, "bin", "pip")
        cls.install_log = run([cls.pip, "install", "--no-build-isolation", "--no-index", "./python"], cwd=cls.src)
        cls.elsewhere = os.path.join(cls.root, "elsewhere")
        os.makedirs(cls.elsewhere)
        fixture = os.path.join(ARGS.source, "tests", "data", "cache_v2.fmc")
        cls.probe = json.loads(run([cls.python, "-c", PROBE, fixture], cwd=cls.elsewhere))

    def test_installs_offline(self):
        self.assertIn("Successfully installed flockmorph-cache-", self.install_log)

    def test_imports_the_installed_module_from_another_directory(self):
        p = self.probe
        site = os.path.join(p["prefix"], "lib")
        self.assertTrue(p["file"].startswith(site + os.sep) and "site-packages" in p["file"], p["file"])
        self.assertEqual(p["prefix"], os.path.realpath(self.venv))
        self.assertEqual(sorted(p["requires"]), ["numpy", "zstandard"])

    def test_reads_a_cache(self):
        """tests/data/cache_v2.fmc: 5 agents, 4 frames at 24 fps (tests/python/test_reader.py)."""
        p = self.probe
        self.assertEqual((p["len"], p["shape"], p["tets_ok"]), (4, [4, 5, 4, 3], True))
        self.assertEqual(p["times"], [k / 24 for k in range(4)])
        self.assertEqual(p["phase"], [[(a + k) % 4 for a in range(5)] for k in (1, 3)])

    def test_version_is_the_projects(self):
        """One version: the CMake project's, as `flockmorph --version` prints it."""
        cli = run([ARGS.cli, "--version"]).split()
        self.assertEqual(cli[0], "flockmorph")
        self.assertEqual((self.probe["version"], self.probe["metadata_version"]), (cli[1], cli[1]))

    def test_uninstalls(self):
        """The module leaves the venv with the package (the other tests use what setUpClass's
        probe found, so the order does not matter)."""
        run([self.pip, "uninstall", "--yes", "flockmorph-cache"])
        with self.assertRaisesRegex(AssertionError, "No module named 'flockmorph_cache'"):
            run([self.python, "-c", "import flockmorph_cache"], cwd=self.elsewhere)


def main():
    global ARGS
    parser = argparse.ArgumentParser()
    for opt in ("--cli", "--tmp", "--source"):
        parser.add_argument(opt, required=True)
    ARGS, rest = parser.parse_known_args()
    os.makedirs(ARGS.tmp, exist_ok=True)
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)


if __name__ == "__main__":
    main()
