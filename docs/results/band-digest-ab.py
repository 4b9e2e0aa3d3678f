# Alternates two builds of the band_digest example on the bay at 5 mm, the builds' order reversed
# every other round, and writes every band's build time (and digest) as one row:
#   python3 docs/results/band-digest-ab.py BEFORE_BIN AFTER_BIN ROUNDS OUT.json
# where each BIN is a copy of target/release/examples/band_digest
# (`cargo build --release -p vps-voxelize --example band_digest`) of the build to compare.
# 'band_ms' builds the inside map itself; 'band_with_kept_inside_map_ms' (builds that print it)
# takes the one the 4-bit voxelization kept.
import json, re, subprocess, sys

before, after, rounds, out_path = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
bins = {"before": before, "after": after}
line_re = re.compile(
    r"standoff (\S+)\s+voxel.*digest (\S+)\s+band\s+([\d.]+) ms"
    r"(?:\s+\(kept inside map\s+([\d.]+) ms\))?\s+4-bit voxelization\s+([\d.]+) ms")
runs = []
for r in range(rounds):
    order = list(bins.items()) if r % 2 == 0 else list(bins.items())[::-1]
    for name, exe in order:
        out = subprocess.run([exe, "aircraft-bay:5"], capture_output=True, text=True, check=True).stdout
        for line in out.splitlines():
            m = line_re.search(line)
            row = {"round": r + 1, "build": name, "standoff_voxels": float(m.group(1)),
                   "digest": m.group(2), "band_ms": float(m.group(3)),
                   "voxelize_4bit_ms": float(m.group(5))}
            if m.group(4):
                row["band_with_kept_inside_map_ms"] = float(m.group(4))
            print(json.dumps(row), flush=True)
            runs.append(row)
json.dump({"runs": runs}, open(out_path, "w"), indent=1)
