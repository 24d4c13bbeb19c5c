#!/usr/bin/env bash
# smokeshadow on a hardware GPU: build in release, run the test suite's GPU-independent checks on
# the hardware adapter, and bench every technique at 2.5k, 65k and 1M particles on it, writing
# every table under one folder (docs/real-gpu.md).
#
#   scripts/gpu-check.sh [-o DIR] [--counts N,N,...] [--tests NAME,...|none] [--cpu]
#                        [--prebuilt DIR] [--studies]
#   scripts/gpu-check.sh --pack DIR [--tests NAME,...]
#
# It picks the adapter `smokeshadow info --adapter auto` selects (hardware first) and names it to
# the tests (SMOKESHADOW_TEST_ADAPTER) and to bench (--adapter), so both run on the same one.
# When that adapter is a CPU (lavapipe) it says so and stops with exit status 3: lavapipe's
# numbers are the README's already. `--cpu` runs everything on lavapipe anyway (to test this
# script; it then defaults to 2,500 particles only, since a million takes lavapipe minutes a
# frame).
#
# A GPU machine without a Rust toolchain or crates.io: `--pack DIR` builds the release binary and
# the release test binaries here and copies them into DIR; copy DIR and this source tree there
# (at the same path: a few tests read their data files by the path they were built at) and run
# `--prebuilt DIR`, which runs those binaries instead of cargo. The bench runs first, then the
# tests, so a run cut short still leaves the tables. `--studies` then measures the rest of the
# GPU tables of docs/real-gpu.md: every technique at 1920x1080 (65k and 1M particles), the
# cloud's coverage study and the thesis sweep (about 3 minutes more on an H200).
set -euo pipefail
cd "$(dirname "$0")/.."

out=gpu-check
counts=""
cpu=0
# The checks that hold on any adapter: closed forms, convergence, probe = render, bounds. Not
# the baselines and the viewer's snapshot (blessed on lavapipe, pixel for pixel), nor the tests
# that drive the binary on lavapipe by name (sweep, cli, compare, gallery, tune).
tests="reference,techniques,gpu_render,probe_render,occluders,point_light,moments,slices,volume,volume_scene,mixed_res,shared_sort,particles,scaling"
prebuilt=""
pack=""
studies=0
# A test binary that hangs (a driver's deadlock) is stopped after this long and reported.
test_timeout=180

while [ $# -gt 0 ]; do
    case "$1" in
    -o) out="$2"; shift 2 ;;
    --counts) counts="$2"; shift 2 ;;
    --tests) tests="$2"; shift 2 ;;
    --cpu) cpu=1; shift ;;
    --prebuilt) prebuilt="$2"; shift 2 ;;
    --pack) pack="$2"; shift 2 ;;
    --studies) studies=1; shift ;;
    -h | --help) sed -n '2,25p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "gpu-check: unknown argument '$1' (see --help)" >&2; exit 2 ;;
    esac
done

start=$(date +%s)
IFS=, read -ra names <<<"$tests"
if [ "$tests" = none ]; then names=(); fi

if [ -n "$pack" ]; then
    echo "gpu-check: building the release binary and test binaries into $pack"
    mkdir -p "$pack/tests"
    cargo build --release --quiet
    cp target/release/smokeshadow "$pack/"
    args=()
    for t in "${names[@]}"; do args+=(--test "$t"); done
    # "Executable tests/NAME.rs (target/release/deps/NAME-HASH)": copy each as tests/NAME.
    cargo test --release --no-run "${args[@]}" 2>&1 |
        sed -n -E 's/^ *Executable tests\/([a-z_0-9]+)\.rs \((.*)\)$/\1 \2/p' |
        while read -r name path; do cp "$path" "$pack/tests/$name"; done
    for t in "${names[@]}"; do
        [ -x "$pack/tests/$t" ] || { echo "gpu-check: test binary $t was not built" >&2; exit 2; }
    done
    echo "gpu-check: packed $(du -sh "$pack" | cut -f1) into $pack; run: scripts/gpu-check.sh --prebuilt $pack"
    exit 0
fi

if [ -n "$prebuilt" ]; then
    [ -d "$prebuilt" ] || { echo "gpu-check: no folder $prebuilt (make it with --pack $prebuilt)" >&2; exit 2; }
    bin="$(cd "$prebuilt" && pwd)/smokeshadow"
    [ -x "$bin" ] || { echo "gpu-check: no binary $bin (make it with --pack $prebuilt)" >&2; exit 2; }
    echo "gpu-check: using the prebuilt binaries in $prebuilt"
else
    echo "gpu-check: building in release"
    cargo build --release --quiet
    bin=target/release/smokeshadow
fi

mkdir -p "$out"
"$bin" info --adapter auto >"$out/info.txt"
selected=$(sed -n 's/^selected (auto): //p' "$out/info.txt")
if [ -z "$selected" ]; then
    echo "gpu-check: no GPU adapter at all (see $out/info.txt); install a Vulkan driver" >&2
    exit 3
fi
# "NAME (TYPE, BACKEND, driver ...)": the name is what precedes the device-type group (a name may
# hold parentheses itself: "llvmpipe (LLVM 15.0.6, 256 bits)").
name=$(sed -E 's/ \((Cpu|DiscreteGpu|IntegratedGpu|VirtualGpu|Other), .*$//' <<<"$selected")
case "$selected" in
*"(Cpu,"*)
    if [ "$cpu" = 0 ]; then
        echo "gpu-check: no hardware GPU adapter: auto selects the CPU adapter $name." >&2
        echo "gpu-check: these checks are for a real GPU; run with --cpu to exercise the script on lavapipe." >&2
        exit 3
    fi
    echo "gpu-check: no hardware GPU adapter; running on the CPU adapter $name as asked (--cpu):"
    echo "gpu-check: these are lavapipe's numbers, not a GPU's"
    counts=${counts:-2500}
    ;;
*)
    echo "gpu-check: hardware adapter: $selected"
    counts=${counts:-2500,65536,1000000}
    ;;
esac
echo "adapter: $selected" >"$out/adapter.txt"

status=0
echo "gpu-check: bench of every technique at $counts particles on $name"
if "$bin" bench --adapter "$name" --particles-list "$counts" -o "$out/bench" \
    >"$out/bench.txt" 2>&1; then
    echo "gpu-check: bench tables in $out/bench.txt, $out/bench/bench.csv"
else
    status=1
    echo "gpu-check: bench failed: see $out/bench.txt" >&2
fi
if grep -q '^  warning:' "$out/bench.txt"; then
    echo "gpu-check: GPU and wall times disagree for some rows (warning lines in $out/bench.txt)"
fi

if [ ${#names[@]} -gt 0 ]; then
    echo "gpu-check: GPU-independent tests ($tests) on $name"
    : >"$out/tests.txt"
    failed=0
    if [ -n "$prebuilt" ]; then
        for t in "${names[@]}"; do
            echo "== $t" >>"$out/tests.txt"
            rc=0
            SMOKESHADOW_TEST_ADAPTER="$name" SMOKESHADOW_TEST_BIN="$bin" \
                timeout "$test_timeout" "$prebuilt/tests/$t" >>"$out/tests.txt" 2>&1 || rc=$?
            if [ $rc = 124 ]; then
                failed=1
                echo "== $t: TIMED OUT after $test_timeout s" >>"$out/tests.txt"
                echo "gpu-check: test binary $t did not finish in $test_timeout s on $name" >&2
            elif [ $rc != 0 ]; then
                failed=1
                echo "gpu-check: test binary $t FAILED on $name: see $out/tests.txt" >&2
            fi
        done
    else
        args=()
        for t in "${names[@]}"; do args+=(--test "$t"); done
        if ! SMOKESHADOW_TEST_ADAPTER="$name" cargo test --release --no-fail-fast "${args[@]}" \
            >"$out/tests.txt" 2>&1; then
            failed=1
            echo "gpu-check: tests FAILED on $name: see $out/tests.txt" >&2
        fi
    fi
    if [ $failed = 0 ]; then
        echo "gpu-check: tests passed ($out/tests.txt)"
    else
        status=1
    fi
    grep -E '^(== |test result)|FAILED|TIMED OUT|panicked' "$out/tests.txt" >"$out/tests-summary.txt" || true
fi

if [ $studies = 1 ]; then
    # name|what|command arguments (docs/real-gpu.md's tables, one file each). On the
    # CPU adapter (--cpu, to test this script) smaller: lavapipe takes minutes for the real ones.
    hd="--size 1920x1080 --particles-list 65536,1000000"
    coverages="0.1,0.3,0.5,0.7,0.9,1.0"
    if [ "$cpu" = 1 ]; then
        hd="--size 640x360 --particles-list $counts --frames 2 --warmup 1"
        coverages="0.6 --frames 2 --warmup 1"
    fi
    for study in \
        "bench_1920x1080|every technique at a larger frame|bench $hd -o $out/bench_1920x1080" \
        "volume_coverage|the cloud's coverage study|bench --volume cloud -t esm,bsm,fom,srm --coverages $coverages -o $out/volume_coverage" \
        "sweep_thesis_plume|the thesis sweep|sweep thesis_plume --techniques all -o $out/sweep_thesis_plume"; do
        IFS='|' read -r file what cmd <<<"$study"
        echo "gpu-check: $what on $name"
        read -ra words <<<"$cmd"
        if ! "$bin" "${words[@]}" --adapter "$name" >"$out/$file.txt" 2>&1; then
            status=1
            echo "gpu-check: $what failed: see $out/$file.txt" >&2
        fi
    done
fi

echo "gpu-check: done in $(($(date +%s) - start)) s, everything under $out/ (status $status)"
exit $status
