#!/usr/bin/env bash
# A benchmark of a base commit against the working tree, run alternately in the same minutes
# (docs/performance.md, "Comparing against a base commit").
#
#   tools/bench-compare.sh [options] [-- BENCH_ARGS...]
#
# Builds the base commit (default: the merge-base of HEAD and main) from `git archive` into a
# temporary folder, Release, only the benchmark's target; builds the working tree the same way (or
# uses --build DIR); then runs the base's benchmark and the current one alternately, A B A B ...,
# for R rounds, with the same BENCH_ARGS, and prints each round's figures and a Markdown summary:
# for each figure the median and min–max of both sides and of the rounds' ratios current/base
# (tools/bench_compare.py). The header names the processor, the date and the exact commands, so
# the output can be pasted into docs/performance.md. The temporary folder is removed on exit.
#
# Exit status: 0 done; 1 usage; 2 a benchmark refused the arguments or failed (the base may not
# have an option or mode that the current tree has); 3 a build failed.
set -euo pipefail

usage() {
    cat <<'EOF'
usage: tools/bench-compare.sh [--base COMMIT] [--rounds R] [--bench NAME] [--bench-source base|current]
                              [--build DIR] [--no-rebuild] [--base-build DIR] [--keep DIR]
                              [--figures REGEX] [-- BENCH_ARGS...]

Runs the benchmark of a base commit (A) and of the working tree (B) alternately, A B A B ...,
with the same arguments, and prints the figures of each round and their medians, spreads and
ratios current/base.

  --base COMMIT      the commit to compare against (default: git merge-base HEAD main)
  --rounds R         rounds of A then B (default 3)
  --bench NAME       the benchmark program: bench_suite (default), bench_step, or another bench/NAME.c
                     that prints one JSON document
  --bench-source S   whose bench/ the base is built with: its own (base, the default), or the
                     working tree's (current: the same benchmark program on both engines, for a
                     base whose benchmark lacks an option or mode, e.g. --mode flock)
  --build DIR        the working tree's build folder, rebuilt for NAME first (default: a Release
                     build in the temporary folder)
  --no-rebuild       use --build DIR's program as it is
  --base-build DIR   an existing build of the base to use as it is, instead of building COMMIT
  --keep DIR         keep every run's JSON and stderr, and the output, in DIR
  --figures REGEX    the figures to show (a Python regular expression over their paths, e.g.
                     'agent_steps_per_second|velocity'; default: throughput, stages, speedup, memory)
  -h, --help         this text

BENCH_ARGS go to both programs, e.g.
  tools/bench-compare.sh -- --agents 1000000 --steps 10 --threads 2
  tools/bench-compare.sh --base 712c02c --rounds 5 -- --mode flock --agents 1000000 --threads 2
  tools/bench-compare.sh --bench bench_step -- --agents 100000 --steps 20 --threads 2
The programs run in the current directory, so a relative --scene names the same file for both;
each side's default scene is its own tree's. Set OMP_WAIT_POLICY=passive on a shared machine.
EOF
}

die() { echo "bench-compare: $1" >&2; exit "${2:-1}"; }

# The whole run is one function, read in full before it starts, so editing this file while it
# runs does not change what runs.
main() {
    ORIG_ARGS=("$@")
    base="" rounds=3 bench=bench_suite bench_source=base build="" rebuild=1 base_build="" keep="" figures=""
    while [ $# -gt 0 ]; do
        case "$1" in
            -h|--help) usage; exit 0 ;;
            --base|--rounds|--bench|--bench-source|--build|--base-build|--keep|--figures)
                [ $# -ge 2 ] || { echo "bench-compare: $1 needs a value" >&2; usage >&2; exit 1; }
                case "$1" in
                    --base) base=$2 ;; --rounds) rounds=$2 ;; --bench) bench=$2 ;; --build) build=$2 ;;
                    --base-build) base_build=$2 ;; --keep) keep=$2 ;; --figures) figures=$2 ;;
                    --bench-source) bench_source=$2 ;;
                esac
                shift 2 ;;
            --no-rebuild) rebuild=0; shift ;;
            --) shift; break ;;
            *) echo "bench-compare: unknown option '$1' (the benchmark's own options go after --)" >&2; usage >&2; exit 1 ;;
        esac
    done
    bench_args=("$@")
    [[ "$rounds" =~ ^[1-9][0-9]*$ ]] || die "--rounds wants a whole number from 1, not '$rounds'"
    [[ "$bench" =~ ^[A-Za-z0-9_]+$ ]] || die "--bench wants a program name such as bench_suite, not '$bench'"
    [ -z "$base" ] || [ -z "$base_build" ] || die "give --base or --base-build, not both"
    [ "$rebuild" = 1 ] || [ -n "$build" ] || die "--no-rebuild needs --build DIR"
    [[ "$bench_source" =~ ^(base|current)$ ]] || die "--bench-source wants base or current, not '$bench_source'"
    [ "$bench_source" = base ] || [ -z "$base_build" ] || die "--bench-source current builds the base: not with --base-build"
    PY=/usr/bin/python3
    [ -x "$PY" ] || die "needs Debian's /usr/bin/python3 (apt-get install python3)"

    here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
    # The working tree; without git (a source tarball) only --base-build with --build can run.
    is_git=1
    root=$(git -C "$here" rev-parse --show-toplevel 2>/dev/null) || { is_git=0; root=$(cd "$here/.." && pwd); }
    [ "$is_git" = 1 ] || { [ -n "$base_build" ] && [ -n "$build" ]; } ||
        die "$root is not a git working tree: give --base-build DIR and --build DIR"
    [ -f "$root/bench/$bench.c" ] || die "the working tree has no bench/$bench.c"
    jobs=$(nproc)

    tmp=$(mktemp -d "${TMPDIR:-/tmp}/bench-compare.XXXXXX")
    cleanup() { rm -rf "$tmp"; }
    trap cleanup EXIT
    trap 'exit 130' INT
    trap 'exit 143' TERM

    # The commit and how it was chosen, or the source folder of --base-build's build.
    short() { git -C "$root" rev-parse --short "$1"; }
    subject() { git -C "$root" log -1 --format=%s "$1" | sed -E 's/^(.{77}).{4,}$/\1.../'; }
    if [ -n "$base_build" ]; then
        [ -x "$base_build/$bench" ] || die "--base-build $base_build has no program $bench"
        base_src=$(sed -n 's/^CMAKE_HOME_DIRECTORY:INTERNAL=//p' "$base_build/CMakeCache.txt" 2>/dev/null || true)
        [ -n "$base_src" ] || die "--base-build $base_build has no CMakeCache.txt naming its source folder"
        base_desc="the build in $base_build, source $base_src$(git -C "$base_src" rev-parse --short HEAD 2>/dev/null | sed 's/^/ at /' || true)"
    else
        if [ -z "$base" ]; then
            commit=$(git -C "$root" merge-base HEAD main 2>/dev/null) || die "no merge-base of HEAD and main: give --base COMMIT"
            how="the merge-base of HEAD and main"
        else
            commit=$(git -C "$root" rev-parse --verify --quiet "$base^{commit}") || die "--base $base is not a commit of $root"
            how="--base $base"
        fi
        base_src=$tmp/base-src
        mkdir -p "$base_src"
        git -C "$root" archive --format=tar "$commit" | tar -x -C "$base_src"
        base_desc="$(short "$commit"), $how: \"$(subject "$commit")\""
        if [ "$bench_source" = current ]; then
            # The working tree's bench/ over the base's (its files replace theirs, the base's others stay).
            cp -R "$root/bench/." "$base_src/bench/"
            base_desc+=", with the working tree's bench/"
        fi
    fi

    # A cheap check before anything is built: every option in BENCH_ARGS must be named in the base's
    # bench/ sources (its parser compares the option as a string). A value the base does not know (a
    # mode it lacks) is caught when its first run refuses it.
    [ -f "$base_src/bench/$bench.c" ] || die "the base ($base_desc) has no bench/$bench.c" 2
    for arg in "${bench_args[@]}"; do
        [[ "$arg" =~ ^--?[A-Za-z] ]] || continue
        grep -rqF -- "\"$arg\"" "$base_src/bench/" ||
            die "the base ($base_desc): its $bench has no option $arg (bench/ never names \"$arg\"), so it cannot run these arguments; choose a later --base, --bench-source current, or drop $arg" 2
    done

    # Configures and builds one benchmark target, Release; the log goes to $3.log, $4 is a hint.
    build_bench() {
        local src=$1 dir=$2 log=$3 hint=${4:-}
        if ! { cmake -S "$src" -B "$dir" -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=OFF &&
               cmake --build "$dir" --target "$bench" -j"$jobs"; } >"$log.log" 2>&1; then
            tail -n 30 "$log.log" >&2
            die "building $bench from $src failed (the log's end is above)$hint" 3
        fi
    }
    build_cmd() { echo "cmake -S $1 -B $2 -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=OFF && cmake --build $2 --target $bench -j$jobs"; }

    if [ -z "$base_build" ]; then
        echo "bench-compare: building the base $(short "$commit") in $tmp (log $tmp/base-build.log)" >&2
        base_build=$tmp/base-build
        hint=""
        [ "$bench_source" = base ] || hint="; the working tree's bench/ may use what this base's engine lacks"
        build_bench "$base_src" "$base_build" "$tmp/base-build" "$hint"
        base_how="git archive $(short "$commit") | tar -x -C $base_src; "
        [ "$bench_source" = base ] || base_how+="cp -R $root/bench/. $base_src/bench/; "
        base_how+=$(build_cmd "$base_src" "$base_build")
    else
        base_how="as it was built"
    fi

    if [ "$is_git" = 1 ]; then
        head_desc=$(short HEAD)
        [ -z "$(git -C "$root" status --porcelain)" ] || head_desc+=" + uncommitted changes"
    else
        head_desc="(not a git tree)"
    fi
    if [ -z "$build" ]; then
        echo "bench-compare: building the working tree in $tmp (log $tmp/current-build.log)" >&2
        build=$tmp/current-build
        build_bench "$root" "$build" "$tmp/current-build"
        current_how=$(build_cmd "$root" "$build")
    elif [ "$rebuild" = 1 ]; then
        echo "bench-compare: bringing $build/$bench up to date" >&2
        cmake --build "$build" --target "$bench" -j"$jobs" >"$tmp/current-build.log" 2>&1 ||
            { tail -n 30 "$tmp/current-build.log" >&2; die "building $bench in $build failed" 3; }
        current_how="cmake --build $build --target $bench -j$jobs"
    else
        current_how="as it was built (--no-rebuild)"
    fi
    [ -x "$build/$bench" ] || die "$build has no program $bench"
    cache_value() { sed -n "s/^$1:[A-Z]*=//p" "$2/CMakeCache.txt" 2>/dev/null || true; }
    warn() { echo "bench-compare: warning: $1" >&2; }
    build_type=$(cache_value CMAKE_BUILD_TYPE "$build")
    [ "$build_type" = Release ] || warn "$build is a '${build_type:-unknown}' build, not Release"
    [ "$(cache_value FM_NATIVE "$build")" != ON ] || warn "$build is built with FM_NATIVE=ON, the base without it"
    build_src=$(cache_value CMAKE_HOME_DIRECTORY "$build")
    [ "$build_src" = "$root" ] || warn "$build was configured from ${build_src:-an unknown folder}, not from $root"
    compiler=$(cache_value CMAKE_C_COMPILER "$build")

    # The machine and the conditions.
    lscpu_field() { lscpu 2>/dev/null | sed -n "s/^$1: *//p" | head -n 1 || true; }
    cpu="$(lscpu_field 'Model name'), family $(lscpu_field 'CPU family') model $(lscpu_field 'Model')"
    flags=$(grep -m1 '^flags' /proc/cpuinfo 2>/dev/null || true)
    has() { [[ " $flags " == *" $1 "* ]] && echo yes || echo no; }
    quote() { local out="" a; for a in "$@"; do out+=" $(printf '%q' "$a")"; done; echo "${out# }"; }
    envs=$(env | grep -E '^(OMP_[A-Z_]*|FM_SIMD|GOMP_[A-Z_]*)=' | sort | tr '\n' ' ' || true)
    base_cmd="${envs}$base_build/$bench $(quote "${bench_args[@]}")"
    current_cmd="${envs}$build/$bench $(quote "${bench_args[@]}")"

    {
        echo "bench-compare: $(date -u '+%Y-%m-%d %H:%M UTC'), $rounds round(s), A = base then B = current"
        echo "machine: $cpu ($(nproc) CPUs; avx2 $(has avx2), avx512f $(has avx512f)); $("${compiler:-cc}" --version 2>/dev/null | head -n 1 || true)"
        echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
        echo "invoked: tools/bench-compare.sh $(quote "${ORIG_ARGS[@]}")"
        echo "base (A): $base_desc"
        echo "          built: $base_how"
        echo "          run:   $base_cmd"
        echo "current (B): $root at $head_desc"
        echo "          built: $current_how"
        echo "          run:   $current_cmd"
    } >"$tmp/header.txt"
    cat "$tmp/header.txt"

    # One run; a failure says which side, how, and what it printed.
    run_one() {
        local side=$1 prog=$2 k=$3 rc=0
        local out=$tmp/$side-$k.json err=$tmp/$side-$k.err
        echo "bench-compare: round $k/$rounds: $side" >&2
        "$prog" "${bench_args[@]}" >"$out" 2>"$err" || rc=$?
        if [ "$rc" != 0 ]; then
            local what="the $side's $bench"
            [ "$side" = base ] && what="the base ($base_desc): its $bench"
            if [ "$rc" = 1 ] && grep -qi 'usage' "$err"; then
                echo "bench-compare: $what refused the arguments: $(grep -v '^$' "$err" | head -n 1)" >&2
                [ "$side" = current ] ||
                    echo "bench-compare: if the current tree takes these arguments, the base lacks an option or value it has: choose a later --base or --bench-source current" >&2
            else
                echo "bench-compare: $what failed with exit status $rc; its stderr ends:" >&2
                tail -n 10 "$err" >&2
            fi
            exit 2
        fi
        "$PY" -c 'import json, sys; json.load(open(sys.argv[1]))' "$out" 2>/dev/null ||
            die "the $side's $bench printed no JSON document (its output is in $out)" 2
    }

    tenths() { local d=$(( ($2 - $1) / 100000000 )); echo "$((d / 10)).$((d % 10))"; }
    for ((k = 1; k <= rounds; k++)); do
        t0=$(date +%s%N); run_one base "$base_build/$bench" "$k"
        t1=$(date +%s%N); run_one current "$build/$bench" "$k"
        t2=$(date +%s%N)
        echo "round $k/$rounds: base $(tenths "$t0" "$t1") s, current $(tenths "$t1" "$t2") s, load average $(cut -d' ' -f1 /proc/loadavg)"
        "$PY" "$here/bench_compare.py" --round "$k" ${figures:+--figures "$figures"} "$tmp/base-$k.json" "$tmp/current-$k.json"
    done | tee "$tmp/rounds.txt"
    # The loop ran in a subshell (the pipe): a failed run's exit status is the pipeline's (pipefail).

    files=()
    for ((k = 1; k <= rounds; k++)); do files+=("$tmp/base-$k.json" "$tmp/current-$k.json"); done
    {
        echo
        echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
        echo
        "$PY" "$here/bench_compare.py" ${figures:+--figures "$figures"} "${files[@]}"
    } | tee "$tmp/summary.txt"

    if [ -n "$keep" ]; then
        mkdir -p "$keep"
        cp "$tmp"/*.json "$tmp"/*.err "$keep"/
        cp "$tmp"/*.log "$keep"/ 2>/dev/null || true
        cat "$tmp/header.txt" "$tmp/rounds.txt" "$tmp/summary.txt" >"$keep/bench-compare.txt"
        echo "bench-compare: kept the runs and this output in $keep" >&2
    fi
}

main "$@"
