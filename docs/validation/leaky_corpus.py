#!/usr/bin/env python3
"""vps's inside/outside on a corpus of public open and leaky meshes, against libigl's generalized
winding number (docs/voxelize.md, "Open and leaky meshes").

The meshes are not in the repository (their licences vary or are unstated): this script fetches
them from two public GitHub repositories at the commits pinned in leaky_corpus_sources.json (or reads them from --from DIR, a folder
holding the files by name), keeps each as its file has it (vertex indices as written: seams whose
sides repeat vertices are open), centres it and scales it to 0.1 m across its largest extent, and
runs the same check as winding_number.py on it at 1 mm voxels: `vps voxelize` + `vps probe` at
random points in the bounding box grown by 10 %, against libigl's exact w at the point and at the
centre of its voxel, points within one voxel of the surface left out.

Usage: python3 docs/validation/leaky_corpus.py [--vps target/release/vps] [--points 10000] [--from DIR]
Writes docs/results/leaky_corpus.json and docs/results/leaky_corpus.md.
Needs numpy, libigl (`import igl`) and trimesh.
"""
import argparse
import json
import os
import sys
import tempfile
import urllib.request

import numpy as np
import trimesh

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import winding_number as wn  # noqa: E402  (the same check, one implementation)

# Where each mesh comes from: file name, repository, pinned commit, path in it, and what the
# repository says of the model (a manifest, like a lock file: the script fetches exactly these).
with open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "leaky_corpus_sources.json")) as f:
    CORPUS = [(m["file"], (m["repository"], m["commit"]), m["path"], m["origin"]) for m in json.load(f)]


def fetch(name, repo, path, folder, cache):
    """The file's bytes: from `folder` when it holds `name`, else downloaded once into `cache`."""
    for where in [folder, cache]:
        if where and os.path.exists(os.path.join(where, name)):
            return os.path.join(where, name)
    url = f"https://raw.githubusercontent.com/{repo[0]}/{repo[1]}/{path}"
    os.makedirs(cache, exist_ok=True)
    target = os.path.join(cache, name)
    with urllib.request.urlopen(url, timeout=60) as r, open(target, "wb") as out:
        out.write(r.read())
    return target


def normalised(file):
    m = trimesh.load(file, process=False, force="mesh", skip_materials=True)
    v, f = np.array(m.vertices, dtype=np.float64), np.array(m.faces, dtype=np.int64)
    area = np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    f = f[area > 0]
    lo, hi = v.min(axis=0), v.max(axis=0)
    v = (v - (lo + hi) / 2) * (0.1 / (hi - lo).max())
    # Off the voxel lattice, as the other checks are.
    return v + np.array([0.0012, -0.0021, 0.0033]), f


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vps", default=os.path.join(wn.ROOT, "target", "release", "vps"))
    ap.add_argument("--points", type=int, default=10000)
    ap.add_argument("--voxel", type=float, default=0.001)
    ap.add_argument("--from", dest="folder", default=None)
    ap.add_argument("--cache", default=os.path.join(tempfile.gettempdir(), "vps-leaky-corpus"))
    ap.add_argument("--out", default=os.path.join(wn.ROOT, "docs", "results"))
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, (name, repo, path, origin) in enumerate(CORPUS):
            v, f = normalised(fetch(name, repo, path, a.folder, a.cache))
            row = wn.check(name.rsplit(".", 1)[0], v, f, a.voxel, a.points, a.vps, tmp, seed=200 + i)
            row.update({"repository": repo[0], "commit": repo[1], "path": path, "origin": origin})
            rows.append(row)
            print(json.dumps(row), flush=True)
    compared = sum(r["compared"] for r in rows)
    total = sum(r["mismatches"] for r in rows)
    centre = sum(r["voxel_centre_mismatches"] for r in rows)
    off_level_set = sum(r["mismatches_off_level_set"] for r in rows)
    summary = {
        "meshes": len(rows),
        "compared": compared,
        "mismatches": total,
        "mismatch_percent": round(100.0 * total / max(compared, 1), 4),
        "mismatches_off_level_set": off_level_set,
        "mismatch_off_level_set_percent": round(100.0 * off_level_set / max(compared, 1), 4),
        "voxel_centre_mismatches": centre,
        "voxel_centre_mismatch_percent": round(100.0 * centre / max(compared, 1), 4),
    }
    os.makedirs(a.out, exist_ok=True)
    with open(os.path.join(a.out, "leaky_corpus.json"), "w") as out:
        json.dump({"command": "python3 docs/validation/leaky_corpus.py", "summary": summary, "rows": rows}, out, indent=1)
    with open(os.path.join(a.out, "leaky_corpus.md"), "w") as out:
        out.write("# vps inside/outside on public open meshes, against libigl's winding number\n\n")
        out.write("Made by `python3 docs/validation/leaky_corpus.py` (see its docstring): each mesh scaled to\n")
        out.write("0.1 m, 1 mm voxels, random points in its box grown by 10 %, points within one voxel of the\n")
        out.write("surface left out. The reference is libigl's exact w of the triangles turned outward by libigl\n")
        out.write("(`bfs_orient`, `orient_outward`; 'turned' counts them). A mismatch is vps Interior where\n")
        out.write("w < 0.5 or vps Free where w >= 0.5. 'Off the w = 1/2 band' leaves out, besides, the\n")
        out.write("mismatches whose voxel straddles the w = 1/2 level set (which spans each opening; vps decides\n")
        out.write("per voxel). 'At voxel centre' compares with w at the centre of the point's voxel (what vps\n")
        out.write("decides on). 'As written' is the plain mismatch count against w of the triangles as the file\n")
        out.write("has them.\n\n")
        out.write("| mesh | from | triangles | boundary edges | turned | points compared | libigl inside | mismatches | % | off the w = 1/2 band | % | at voxel centre | % | as written |\n")
        out.write("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n")
        for r in rows:
            out.write(
                f"| {r['mesh']} | {r['repository']} `{r['path']}` | {r['triangles']} | {r['boundary_edges']} | "
                f"{r['triangles_turned_by_libigl']} | "
                f"{r['compared']} | {r['igl_inside']} | {r['mismatches']} | {r['mismatch_percent']} | "
                f"{r['mismatches_off_level_set']} | {r['mismatch_off_level_set_percent']} | "
                f"{r['voxel_centre_mismatches']} | {r['voxel_centre_mismatch_percent']} | "
                f"{r['mismatches_against_w_as_written']} |\n"
            )
        out.write(
            f"\nAll: {summary['mismatches']} mismatches of {summary['compared']} points "
            f"({summary['mismatch_percent']} %); off the w = 1/2 band {summary['mismatches_off_level_set']} "
            f"({summary['mismatch_off_level_set_percent']} %); at voxel centres {summary['voxel_centre_mismatches']} "
            f"({summary['voxel_centre_mismatch_percent']} %).\n"
        )
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
