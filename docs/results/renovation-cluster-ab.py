# Alternates two vps release builds on `vps cluster --local-workers 2`, split always and predicted,
# ROUNDS rounds, from the repository root; prints one JSON line per run and writes them all to
# OUT. Usage (build the two binaries first, e.g. a `git worktree` of the old commit):
#   python3 docs/results/renovation-cluster-ab.py ROUNDS OLD_VPS NEW_VPS OUT.json
import json, subprocess, sys, time
bins = {"before_19a88e9": sys.argv[2], "after": sys.argv[3]}
modes = {
  "split_always": ["cluster", "--local-workers", "2", "--split", "always", "--max-stale-frames", "0", "--seconds", "15", "--json"],
  "predicted_split": ["cluster", "--local-workers", "2", "--seconds", "15", "--json"],
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
            s = rep["stats"]; c = rep["cluster"]
            peers = [{"p50_ns": q["rtt_ns"]["p50"], "p999_ns": q["rtt_ns"]["p999"], "samples": q["rtt_samples"], "late": q.get("late"), "lost": q.get("lost")} for q in c["peers"]]
            row = {"round": r + 1, "build": name, "mode": mode, "frames": s["frames"], "missed_deadlines": s["missed_deadlines"],
                   "compute_p50_ns": s["compute_ns"]["p50"], "compute_p999_ns": s["compute_ns"]["p999"],
                   "fallback_shares": c.get("fallback_shares"), "stale_shares": c.get("stale_shares"), "peers": peers,
                   "wall_s": round(time.time() - t, 1)}
            print(json.dumps(row), flush=True)
            out["runs"].append(row)
json.dump(out, open(sys.argv[4], "w"), indent=1)
