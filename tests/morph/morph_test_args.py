"""The arguments every python test of tests/morph takes from ctest (tests/CMakeLists.txt): --cli (the
flockmorph binary), --tmp (a folder for its outputs, made here) and --source (the project's root);
and how each ends: every failure printed, exit 1 if any."""
import argparse
import os


def parse_args(description=None):
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--cli", required=True)
    ap.add_argument("--tmp", required=True)
    ap.add_argument("--source", required=True)
    args = ap.parse_args()
    os.makedirs(args.tmp, exist_ok=True)
    return args


def finish(failures):
    """Prints each failure and returns the test's exit status."""
    for f in failures:
        print("FAIL:", f)
    return 1 if failures else 0
