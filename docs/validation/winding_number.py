#!/usr/bin/env python3
"""Independent check of vps's inside/outside on open and leaky meshes against libigl's winding
number (docs/voxelize.md, "Open and leaky meshes").

For each mesh: write it as OBJ (metres), `vps voxelize MESH --voxel-size S --offset 0 --width 2`, sample
random points in its bounding box grown by 10 %, `vps probe --points --json` them, and compare vps's
answer (Interior = inside, Free = outside) with libigl's exact generalized winding number
(w >= 0.5 = inside) of the triangles turned to face outward by libigl (`bfs_orient`, then
`orient_outward`, which shoots rays; vps turns them by its own rule before its winding number), and
with w of the triangles as written (reported apart: a mesh exported clockwise has w = -1 inside). Points closer than one voxel to the surface (libigl's point-mesh distance) are
left out (the band); points outside the band that land in a Surface voxel are counted apart, not as
mismatches.

Usage: python3 docs/validation/winding_number.py [--vps target/release/vps] [--points 10000]
Writes docs/results/winding_number.json and docs/results/winding_number.md.
Needs numpy, libigl (`import igl`) and trimesh.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import igl
import numpy as np
import trimesh

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def box_faces_without(drop_top):
    """A 0.1 m cube (half extent 0.05) centred off the voxel lattice; optionally no +z face."""
    m = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    v, f = np.array(m.vertices), np.array(m.faces)
    if drop_top:
        keep = ~np.all(np.isclose(v[f][:, :, 2], 0.05), axis=1)
        f = f[keep]
    return v + np.array([0.0012, -0.0021, 0.0033]), f


def slit_box():
    """The open box with a lid 2.5 mm larger than the opening floating 12.5 mm above it: a slit all
    round, 2.5 voxels tall at 5 mm."""
    v, f = box_faces_without(True)
    h, z = 0.0525, 0.05 + 0.0125
    c = np.array([0.0012, -0.0021, 0.0033])
    lid_v = np.array([[-h, -h, z], [h, -h, z], [h, h, z], [-h, h, z]]) + c
    lid_f = np.array([[0, 1, 2], [0, 2, 3]]) + len(v)
    return np.vstack([v, lid_v]), np.vstack([f, lid_f])


def holey_sphere(seed=7):
    """An icosphere of radius 0.05 m with 5 % of its faces removed at random (holes)."""
    m = trimesh.creation.icosphere(subdivisions=4, radius=0.05)
    rng = np.random.default_rng(seed)
    keep = rng.random(len(m.faces)) > 0.05
    return np.array(m.vertices), np.array(m.faces)[keep]


def bernstein(t):
    return np.array([(1 - t) ** 3, 3 * t * (1 - t) ** 2, 3 * t * t * (1 - t), t ** 3])


def teapot(n=12):
    """The Bezier teapot of assets/teapot-bezier.txt tessellated n x n per patch (patches not
    welded: seams are open), zero-area triangles dropped, oriented to positive volume, scaled to
    0.075 m long like vps's builtin."""
    lines = [
        l.split()
        for l in open(os.path.join(ROOT, "assets", "teapot-bezier.txt"))
        if l.strip() and not l.startswith("#")
    ]
    nv = int(lines[0][1])
    pts = np.array([[float(x) for x in l] for l in lines[1 : 1 + nv]])
    npatch = int(lines[1 + nv][1])
    patches = [[int(x) for x in l] for l in lines[2 + nv : 2 + nv + npatch]]
    verts, faces = [], []
    ts = np.linspace(0.0, 1.0, n + 1)
    basis = np.array([bernstein(t) for t in ts])  # (n+1, 4)
    for p in patches:
        ctrl = pts[p].reshape(4, 4, 3)
        grid = np.einsum("ui,vj,ijk->uvk", basis, basis, ctrl)
        base = len(verts)
        verts.extend(grid.reshape(-1, 3))
        for i in range(n):
            for j in range(n):
                a = base + i * (n + 1) + j
                b, c, d = a + 1, a + n + 1, a + n + 2
                faces.append([a, c, d])
                faces.append([a, d, b])
    v, f = np.array(verts), np.array(faces)
    area = np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    f = f[area > 1e-12]
    vol = np.sum(np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]]))) / 6.0
    if vol < 0:
        f = f[:, ::-1]
    v = v * (0.075 / (v[:, 0].max() - v[:, 0].min()))
    return v, f


def boundary_edges(f):
    e = np.sort(np.vstack([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    return int(np.sum(counts == 1))


def write_obj(path, v, f):
    with open(path, "w") as out:
        for p in v:
            out.write(f"v {p[0]:.9f} {p[1]:.9f} {p[2]:.9f}\n")
        for t in f:
            out.write(f"f {t[0] + 1} {t[1] + 1} {t[2] + 1}\n")


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{r.stderr}")
    return r.stdout


def check(name, v, f, voxel, n_points, vps, tmp, seed):
    obj = os.path.join(tmp, f"{name}.obj")
    vmap = os.path.join(tmp, f"{name}.vmap")
    csv = os.path.join(tmp, f"{name}.csv")
    write_obj(obj, v, f)
    t0 = time.time()
    run([vps, "voxelize", obj, "--voxel-size", str(voxel), "--offset", "0", "--width", "2", "-o", vmap])
    vox_s = time.time() - t0
    lo, hi = v.min(axis=0), v.max(axis=0)
    pad = 0.1 * (hi - lo)
    rng = np.random.default_rng(seed)
    p = rng.uniform(lo - pad, hi + pad, size=(n_points, 3))
    np.savetxt(csv, p, delimiter=",", fmt="%.9f")
    kinds = [r["kind"] for r in json.loads(run([vps, "probe", vmap, "--points", csv, "--json"]))]
    v = v.astype(np.float64)
    # The reference: libigl's w of the triangles turned outward by libigl (bfs_orient makes each
    # patch agree, orient_outward turns it by shooting rays), as vps turns them before its own
    # winding number. As written, a mesh exported clockwise has w = -1 inside.
    written = f.astype(np.int64)
    agreed, patches = igl.bfs_orient(written)
    f, _ = igl.orient_outward(
        v, np.ascontiguousarray(agreed, dtype=np.int64), np.ascontiguousarray(patches, dtype=np.int64).reshape(-1, 1)
    )
    # Reversed triangles (bfs_orient may also rotate a triangle's corners, which turns nothing).
    kept = np.zeros(len(f), dtype=bool)
    for k in range(3):
        kept |= np.all(f == np.roll(written, k, axis=1), axis=1)
    turned = int((~kept).sum())
    w = igl.winding_number(v, f, p)
    w_written = igl.winding_number(v, written, p)
    d2, _, _ = igl.point_mesh_squared_distance(p, v.astype(np.float64), f.astype(np.int64))
    far = np.sqrt(d2) >= voxel
    igl_in = w >= 0.5
    # The centre of the voxel each point falls in (grids start on a multiple of the voxel size):
    # vps decides per voxel centre, so a point whose own w is on the other side of 0.5 than its
    # voxel centre's is a discretization difference, not an error of the winding number.
    centres = (np.floor(p / voxel) + 0.5) * voxel
    wc = igl.winding_number(v.astype(np.float64), f.astype(np.int64), centres)
    vps_in = np.array([k == "interior" for k in kinds])
    decided = np.array([k in ("interior", "free") for k in kinds])
    compared = far & decided
    mismatch = compared & (igl_in != vps_in)
    centre_mismatch = compared & ((wc >= 0.5) != vps_in)
    # A mismatch at the point whose voxel straddles the w = 1/2 level set (w at some corner of the
    # voxel on the other side from w at the point): the level set spans an opening, and vps, which
    # decides per voxel, cannot place it closer than a voxel; like the surface band, a
    # discretization, not an error of the winding number.
    straddles = np.zeros(len(p), dtype=bool)
    idx = np.flatnonzero(mismatch)
    if len(idx):
        lo_corner = np.floor(p[idx] / voxel) * voxel
        for corner in np.array(np.meshgrid([0, 1], [0, 1], [0, 1])).T.reshape(-1, 3):
            wk = igl.winding_number(v, f, lo_corner + corner * voxel)
            straddles[idx] |= (wk >= 0.5) != igl_in[idx]
    off_level_set = mismatch & ~straddles
    return {
        "mesh": name,
        "triangles": int(len(f)),
        "boundary_edges": boundary_edges(f),
        "voxel_size_m": voxel,
        "points": int(n_points),
        "outside_band": int(far.sum()),
        "compared": int(compared.sum()),
        "surface_voxel_outside_band": int((far & ~decided).sum()),
        "igl_inside": int((compared & igl_in).sum()),
        "mismatches": int(mismatch.sum()),
        "mismatch_percent": round(100.0 * mismatch.sum() / max(compared.sum(), 1), 4),
        "mismatch_igl_w": [round(float(x), 3) for x in w[mismatch][:10]],
        "mismatches_off_level_set": int(off_level_set.sum()),
        "mismatch_off_level_set_percent": round(100.0 * off_level_set.sum() / max(compared.sum(), 1), 4),
        "triangles_turned_by_libigl": turned,
        "mismatches_against_w_as_written": int((compared & ((w_written >= 0.5) != vps_in)).sum()),
        "vps_interior_igl_outside": int((mismatch & vps_in).sum()),
        "vps_free_igl_inside": int((mismatch & ~vps_in).sum()),
        # Orientation-free: |w| >= 0.5 is inside (a solid whose faces all point inward has w = -1).
        "abs_w_mismatches": int((compared & ((np.abs(w) >= 0.5) != vps_in)).sum()),
        "voxel_centre_mismatches": int(centre_mismatch.sum()),
        # Those whose voxel centre's w is at least 0.05 from 0.5: not within the hierarchical
        # approximation's error of the level set.
        "voxel_centre_mismatches_w_off_half_by_0_05": int(
            (centre_mismatch & (np.abs(wc - 0.5) >= 0.05)).sum()
        ),
        "voxel_centre_mismatch_percent": round(
            100.0 * centre_mismatch.sum() / max(compared.sum(), 1), 4
        ),
        "voxelize_s": round(vox_s, 2),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vps", default=os.path.join(ROOT, "target", "release", "vps"))
    ap.add_argument("--points", type=int, default=10000)
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "results"))
    a = ap.parse_args()
    meshes = [
        ("open-box", *box_faces_without(True), 0.005),
        ("slit-box", *slit_box(), 0.005),
        ("holey-sphere", *holey_sphere(), 0.002),
        ("teapot", *teapot(), 0.001),
        ("closed-box", *box_faces_without(False), 0.005),
    ]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, (name, v, f, voxel) in enumerate(meshes):
            rows.append(check(name, v, f, voxel, a.points, a.vps, tmp, seed=100 + i))
            print(json.dumps(rows[-1]))
    os.makedirs(a.out, exist_ok=True)
    with open(os.path.join(a.out, "winding_number.json"), "w") as out:
        json.dump({"command": "python3 docs/validation/winding_number.py", "rows": rows}, out, indent=1)
    with open(os.path.join(a.out, "winding_number.md"), "w") as out:
        out.write("# vps inside/outside against libigl's winding number\n\n")
        out.write("Made by `python3 docs/validation/winding_number.py` (see its docstring). Points closer\n")
        out.write("than one voxel to the surface are left out; libigl's w is of the triangles turned outward\n")
        out.write("by libigl (bfs_orient, orient_outward); a mismatch is vps Interior where libigl's\n")
        out.write("w < 0.5, or vps Free where w >= 0.5. 'At voxel centre' compares vps with libigl's w at\n")
        out.write("the centre of the voxel the point falls in (what vps decides on): the rest of the\n")
        out.write("point mismatches are voxel discretization across the w = 0.5 level set.\n\n")
        out.write("| mesh | triangles | boundary edges | voxel (m) | points compared | in Surface voxels beyond the band | libigl inside | mismatches | % | at voxel centre | % |\n")
        out.write("|---|---|---|---|---|---|---|---|---|---|---|\n")
        for r in rows:
            out.write(
                f"| {r['mesh']} | {r['triangles']} | {r['boundary_edges']} | {r['voxel_size_m']} | "
                f"{r['compared']} | {r['surface_voxel_outside_band']} | {r['igl_inside']} | "
                f"{r['mismatches']} | {r['mismatch_percent']} | "
                f"{r['voxel_centre_mismatches']} | {r['voxel_centre_mismatch_percent']} |\n"
            )
    total = sum(r["mismatches"] for r in rows)
    compared = sum(r["compared"] for r in rows)
    centre = sum(r["voxel_centre_mismatches"] for r in rows)
    print(f"total mismatches {total} of {compared} ({100.0 * total / max(compared, 1):.4f} %)")
    print(f"at voxel centres {centre} of {compared} ({100.0 * centre / max(compared, 1):.4f} %)")


if __name__ == "__main__":
    main()
