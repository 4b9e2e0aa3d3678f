# Runs two vps builds alternately on the same commands, from the repository root: in each round
# every mode runs once per build, the builds' order reversed every other round. Each run's --json
# report becomes one row (`row_of` picks its figures); the rows are printed as they come and
# written to OUT as {"runs": [...]}. Used by renovation-cluster-ab.py and one-sampler-ab.py.
import json, subprocess, sys, time


def alternate(bins, modes, rounds, row_of, out_path):
    out = {"runs": []}
    for r in range(rounds):
        order = list(bins.items()) if r % 2 == 0 else list(bins.items())[::-1]
        for mode, args in modes.items():
            for name, exe in order:
                t = time.time()
                p = subprocess.run([exe] + args, capture_output=True, text=True, cwd=".")
                if p.returncode != 0:
                    print(name, mode, "rc", p.returncode, p.stderr[-2000:]); sys.exit(1)
                row = {"round": r + 1, "build": name, "mode": mode, **row_of(json.loads(p.stdout)),
                       "wall_s": round(time.time() - t, 1)}
                print(json.dumps(row), flush=True)
                out["runs"].append(row)
    json.dump(out, open(out_path, "w"), indent=1)
