# Alternates two vps release builds (before and after the cluster's own share and its workers
# moved from rayon pools onto the runtime's ClassPool) on three runs, ROUNDS rounds, from the
# repository root; prints one JSON line per run and writes them all to OUT. Usage:
#   python3 docs/results/one-sampler-ab.py ROUNDS BEFORE_VPS AFTER_VPS OUT.json
import os, sys
sys.dont_write_bytecode = True  # no __pycache__ under docs/results
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from alternate_builds import alternate
bins = {"before": sys.argv[2], "after": sys.argv[3]}
modes = {
  # Split every frame; the coordinator and each worker on one thread (no pool thread either way).
  "cluster_2_workers_1_thread": ["cluster", "--local-workers", "2", "--split", "always", "--max-stale-frames", "0", "--seconds", "15", "--json"],
  # One worker of two threads, the coordinator on two: both sides' pools work every frame.
  "cluster_1_worker_2_threads": ["cluster", "--local-workers", "1", "--worker-threads", "2", "--threads", "2", "--split", "always", "--max-stale-frames", "0", "--seconds", "15", "--json"],
  # The 1 kHz loop's own pool: 100k points on two threads.
  "loop_100k_2_threads": ["bench", "loop", "--points", "100000", "--frames", "10000", "--threads", "2", "--json"],
}


def row_of(rep):
    s = rep["stats"]
    row = {"frames": s["frames"], "missed_deadlines": s["missed_deadlines"],
           "compute_p50_ns": s["compute_ns"]["p50"], "compute_p999_ns": s["compute_ns"]["p999"]}
    c = rep.get("cluster")
    if c:
        row["fallback_shares"] = c.get("fallback_shares")
        row["peers"] = [{"p50_ns": q["rtt_ns"]["p50"], "p999_ns": q["rtt_ns"]["p999"], "samples": q["rtt_samples"], "late": q.get("late")} for q in c["peers"]]
    return row


alternate(bins, modes, int(sys.argv[1]), row_of, sys.argv[4])
