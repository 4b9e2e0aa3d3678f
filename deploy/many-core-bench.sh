#!/usr/bin/env bash
# many-core-bench.sh: the benchmarks to run on a lent many-core machine, given a stripped release
# `vps` binary. Needs no toolchain and no network (the cluster runs on loopback).
#
#   deploy/many-core-bench.sh VPS_BINARY OUT_DIR
#
# Writes into OUT_DIR (created):
#   machine.txt             CPU model, cores, kernel, load average before and after
#   kernel.json             vps bench kernel (previous and current kernel alternated)
#   scaling.json/.svg       vps bench scaling (1..N threads and 1..N worker processes)
#   cluster-wW.json         vps bench cluster --points 100000 --workers W, W = 1 2 4 8
#   host.json               vps bench host (how often the machine takes the frame thread's core)
#   stderr/*.log            each command's stderr
#
# Environment (defaults in brackets):
#   VPS_FRAMES    frames per cluster run and per scaling run [10000]
#   VPS_MAX       largest thread / worker count for the scaling run [all cores]
#   VPS_HOST_S    seconds of vps bench host [60]
# Runs one benchmark at a time; nothing else should run on the machine meanwhile.
set -euo pipefail

if [[ $# -ne 2 ]]; then
    echo "usage: $0 VPS_BINARY OUT_DIR" >&2
    exit 2
fi
vps=$1
out=$2
if [[ ! -x $vps ]]; then
    echo "$0: $vps is not an executable file" >&2
    exit 2
fi
frames=${VPS_FRAMES:-10000}
max=${VPS_MAX:-$(nproc)}
host_s=${VPS_HOST_S:-60}
for v in "$frames" "$max" "$host_s"; do
    if ! [[ $v =~ ^[1-9][0-9]*$ ]]; then
        echo "$0: VPS_FRAMES, VPS_MAX and VPS_HOST_S must be positive integers (got '$v')" >&2
        exit 2
    fi
done
mkdir -p "$out/stderr"

machine() {
    echo "== $1"
    grep -m1 'model name' /proc/cpuinfo || true
    echo "cores: $(nproc)"
    uname -srm
    cat /proc/loadavg
}

# run NAME ARGS...: vps ARGS --json > OUT_DIR/NAME.json, stderr to OUT_DIR/stderr/NAME.log.
run() {
    local name=$1
    shift
    echo "$(date -u +%H:%M:%S) vps $* --json" >&2
    "$vps" "$@" --json >"$out/$name.json" 2>"$out/stderr/$name.log"
}

machine before >"$out/machine.txt"
run kernel bench kernel
run scaling bench scaling --max "$max" --frames "$frames" --plot "$out/scaling.svg"
for w in 1 2 4 8; do
    if ((w + 1 <= $(nproc))); then
        run "cluster-w$w" bench cluster --points 100000 --frames "$frames" --workers "$w"
    else
        echo "skipping --workers $w: $(nproc) cores" >&2
    fi
done
run host bench host --seconds "$host_s"
machine after >>"$out/machine.txt"
echo "done: $out" >&2
