# Alternates two vps release builds on `vps cluster --local-workers 2`, split always and predicted,
# ROUNDS rounds, from the repository root; prints one JSON line per run and writes them all to
# OUT. Usage (build the two binaries first, e.g. a `git worktree` of the old commit):
#   python3 docs/results/renovation-cluster-ab.py ROUNDS OLD_VPS NEW_VPS OUT.json
import os, sys
sys.dont_write_bytecode = True  # no __pycache__ under docs/results
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from alternate_builds import alternate
bins = {"before_19a88e9": sys.argv[2], "after": sys.argv[3]}
modes = {
  "split_always": ["cluster", "--local-workers", "2", "--split", "always", "--max-stale-frames", "0", "--seconds", "15", "--json"],
  "predicted_split": ["cluster", "--local-workers", "2", "--seconds", "15", "--json"],
}


def row_of(rep):
    s = rep["stats"]; c = rep["cluster"]
    peers = [{"p50_ns": q["rtt_ns"]["p50"], "p999_ns": q["rtt_ns"]["p999"], "samples": q["rtt_samples"], "late": q.get("late"), "lost": q.get("lost")} for q in c["peers"]]
    return {"frames": s["frames"], "missed_deadlines": s["missed_deadlines"],
            "compute_p50_ns": s["compute_ns"]["p50"], "compute_p999_ns": s["compute_ns"]["p999"],
            "fallback_shares": c.get("fallback_shares"), "stale_shares": c.get("stale_shares"), "peers": peers}


alternate(bins, modes, int(sys.argv[1]), row_of, sys.argv[4])
