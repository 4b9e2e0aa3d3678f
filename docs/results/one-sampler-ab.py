# Alternates two vps release builds (before and after the cluster's own share and its workers
# moved from rayon pools onto the runtime's ClassPool) on three runs, ROUNDS rounds, from the
# repository root; prints one JSON line per run and writes them all to OUT. Usage:
#   python3 docs/results/one-sampler-ab.py ROUNDS BEFORE_VPS AFTER_VPS OUT.json
import json, subprocess, sys, time
bins = {"before": sys.argv[2], "after": sys.argv[3]}
modes = {
  # Split every frame; the coordinator and each worker on one thread (no pool thread either way).
  "cluster_2_workers_1_thread": ["cluster", "--local-workers", "2", "--split", "always", "--max-stale-frames", "0", "--seconds", "15", "--json"],
  # One worker of two threads, the coordinator on two: both sides' pools work every frame.
  "cluster_1_worker_2_threads": ["cluster", "--local-workers", "1", "--worker-threads", "2", "--threads", "2", "--split", "always", "--max-stale-frames", "0", "--seconds", "15", "--json"],
  # The 1 kHz loop's own pool: 100k points on two threads.
  "loop_100k_2_threads": ["bench", "loop", "--points", "100000", "--frames", "10000", "--threads", "2", "--json"],
}
rounds = int(sys.argv[1])
out = {"runs": []}
for r in range(rounds):
    order = list(bins.items()) if r % 2 == 0 else list(bins.items())[::-1]
    for mode, args in modes.items():
        for name, exe in order:
            t = time.time()
            p = subprocess.run([exe] + args, capture_output=True, text=True, cwd=".")
            if p.returncode != 0:
                print(name, mode, "rc", p.returncode, p.stderr[-2000:]); sys.exit(1)
            rep = json.loads(p.stdout)
            s = rep["stats"]
            row = {"round": r + 1, "build": name, "mode": mode, "frames": s["frames"],
                   "missed_deadlines": s["missed_deadlines"],
                   "compute_p50_ns": s["compute_ns"]["p50"], "compute_p999_ns": s["compute_ns"]["p999"],
                   "wall_s": round(time.time() - t, 1)}
            c = rep.get("cluster")
            if c:
                row["fallback_shares"] = c.get("fallback_shares")
                row["peers"] = [{"p50_ns": q["rtt_ns"]["p50"], "p999_ns": q["rtt_ns"]["p999"], "samples": q["rtt_samples"], "late": q.get("late")} for q in c["peers"]]
            print(json.dumps(row), flush=True)
            out["runs"].append(row)
json.dump(out, open(sys.argv[4], "w"), indent=1)
