#!/usr/bin/env bash
# The cluster criterion of issue 18, measured alternately in one run: ROUNDS rounds of
#   vps run --seconds 10 --json
#   vps cluster --local-workers 2 --seconds 10 --json                  (split "predict")
#   vps cluster --local-workers 2 --seconds 10 --split always --json
# on the demo scene, and ONE consolidated JSON at OUT.json: per round the three compute p50 / p99 /
# p99.9 (ns), missed deadlines, the placement the cluster runs reported, the ratios predict/run and
# always/run of p99.9; a summary of the rounds whose p99.9 ratio is within 1.5x; the command line.
#
# Usage: benches/cluster-demo-alternation.sh ROUNDS OUT.json
# Env:   VPS (default target/release/vps), VPS_CACHE_DIR (default target/vps-cache).
set -euo pipefail

if [ $# -ne 2 ] || ! [[ $1 =~ ^[1-9][0-9]*$ ]]; then
  echo "usage: $0 ROUNDS OUT.json" >&2
  exit 2
fi
rounds=$1
out=$2
vps=${VPS:-target/release/vps}
export VPS_CACHE_DIR=${VPS_CACHE_DIR:-$PWD/target/vps-cache}
[ -x "$vps" ] || { echo "$0: $vps is not an executable (set VPS)" >&2; exit 2; }
command -v python3 >/dev/null || { echo "$0: needs python3" >&2; exit 2; }

raw=$(mktemp -d)
trap 'rm -rf "$raw"' EXIT
for r in $(seq 1 "$rounds"); do
  echo "round $r of $rounds" >&2
  "$vps" run --seconds 10 --json > "$raw/run-$r.json"
  "$vps" cluster --local-workers 2 --seconds 10 --json > "$raw/predict-$r.json"
  "$vps" cluster --local-workers 2 --seconds 10 --split always --json > "$raw/always-$r.json"
done

python3 - "$raw" "$rounds" "$out" "$0 $*" "$vps" <<'EOF'
import json, os, sys, platform
raw, rounds, out, command, vps = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4], sys.argv[5]
BOUND = 1.5

def figures(path):
    d = json.load(open(path))
    c = d["stats"]["compute_ns"]
    f = {
        "compute_p50_ns": c["p50"],
        "compute_p99_ns": c["p99"],
        "compute_p999_ns": c["p999"],
        "missed_deadlines": d["stats"]["missed_deadlines"],
        "frames": d["stats"]["frames"],
        "realtime_granted": d["realtime_granted"],
    }
    placement = (d.get("cluster") or {}).get("placement")
    if placement is not None or "cluster" in d:
        f["placement"] = placement
    return f

per_round = []
for r in range(1, rounds + 1):
    row = {"round": r}
    for mode in ("run", "predict", "always"):
        row[mode] = figures(os.path.join(raw, f"{mode}-{r}.json"))
    base = row["run"]["compute_p999_ns"]
    for mode in ("predict", "always"):
        row[f"{mode}_over_run_p999"] = round(row[mode]["compute_p999_ns"] / base, 3)
    per_round.append(row)

report = {
    "command": command,
    "vps": vps,
    "runs": {
        "run": "vps run --seconds 10 --json",
        "predict": "vps cluster --local-workers 2 --seconds 10 --json",
        "always": "vps cluster --local-workers 2 --seconds 10 --split always --json",
    },
    "cores": len(os.sched_getaffinity(0)),
    "load_average_at_end": os.getloadavg(),
    "bound": f"compute p99.9 within {BOUND}x of the one-process run's",
    "rounds": per_round,
    "summary": {
        "rounds": rounds,
        "predict_within_bound": sum(r["predict_over_run_p999"] <= BOUND for r in per_round),
        "always_within_bound": sum(r["always_over_run_p999"] <= BOUND for r in per_round),
        "predict_over_run_p999": [r["predict_over_run_p999"] for r in per_round],
        "always_over_run_p999": [r["always_over_run_p999"] for r in per_round],
    },
}
with open(out, "w") as f:
    json.dump(report, f, indent=1)
    f.write("\n")
s = report["summary"]
print(f"predict p99.9 within {BOUND}x of run in {s['predict_within_bound']} of {rounds} rounds: {s['predict_over_run_p999']}")
print(f"always  p99.9 within {BOUND}x of run in {s['always_within_bound']} of {rounds} rounds: {s['always_over_run_p999']}")
EOF
