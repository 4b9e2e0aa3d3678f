#!/usr/bin/env python3
"""Independent check of the exact clearance in vps's assembly studies (docs/study.md) against the
Flexible Collision Library (python-fcl: mesh-mesh distance over its own OBB/RSS hierarchies).

For each example scene (assets/scenes/peg-in-hole.toml, assets/scenes/bracket-in-bay.toml):
`vps run --scene S --seconds N --study DIR` in a scratch folder; read the part's mesh the study
wrote (DIR/part.obj, its grip frame), place the scene's static meshes from the scene file here
(units, scale, rotate_deg about X then Y then Z, translate, as docs/scenes.md says), pose the part
at every frame of DIR/path.csv and ask FCL for the distance to each static object. Compared:
- vps's clearance series (DIR/clearance.csv, every 10th frame) with FCL's at the same frames;
- vps's minimum over the whole path (study.json) with FCL's minimum over every frame, and the
  frame each says it happens at.
And for a scene of two moving parts (assets/scenes/two-hands.toml): each part's mesh and path from
its folder (DIR/<part>/part.obj, path.csv), both posed at every frame, FCL's distance between the
two against vps's pair clearance (DIR/pair_clearance.csv every 10th frame, DIR/pairs.json's
minimum over every frame).

Usage: python3 docs/validation/study_clearance.py [--vps target/release/vps]
Writes docs/results/study_clearance.json and docs/results/study_clearance.md.
Needs numpy, trimesh and python-fcl (`pip install numpy trimesh python-fcl`).
"""
import argparse
import csv
import json
import math
import os
import shutil
import subprocess
import tempfile
import time
import tomllib

import fcl
import numpy as np
import trimesh

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}
SCENES = [("peg-in-hole", "3"), ("bracket-in-bay", "8")]


def rotation_xyz(deg):
    """The scene file's rotate_deg: about X, then Y, then Z (a 3x3 matrix acting on columns)."""
    rx, ry, rz = (math.radians(d) for d in deg)
    cx, sx, cy, sy, cz, sz = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry), math.cos(rz), math.sin(rz)
    x = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    y = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    z = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return z @ y @ x


def load(path):
    m = trimesh.load(path, force="mesh", process=False)
    return np.asarray(m.vertices, dtype=float), np.asarray(m.faces, dtype=np.int64)


def placed_statics(scene_path):
    with open(scene_path, "rb") as f:
        scene = tomllib.load(f)
    base = os.path.dirname(scene_path)
    out = []
    for o in scene["static"]:
        v, f = load(os.path.join(base, o["source"]))
        v = v * UNITS[o.get("units", "m")]
        scale = o.get("scale", [1.0, 1.0, 1.0])
        if not isinstance(scale, list):
            scale = [scale] * 3
        v = v * np.array(scale)
        v = v @ rotation_xyz(o.get("rotate_deg", [0, 0, 0])).T
        v = v + np.array(o.get("translate", [0, 0, 0]))
        out.append((v, f))
    return out


def bvh(v, f):
    m = fcl.BVHModel()
    m.beginModel(len(v), len(f))
    m.addSubModel(v, f)
    m.endModel()
    return m


def distance(part, pose, obj):
    p, q = pose
    a = fcl.CollisionObject(part, fcl.Transform(np.array([q[3], q[0], q[1], q[2]]), p))
    b = fcl.CollisionObject(obj, fcl.Transform())
    d = fcl.distance(a, b, fcl.DistanceRequest(enable_nearest_points=True), fcl.DistanceResult())
    return max(d, 0.0)


def study_scene(vps, name, seconds, scratch):
    work = os.path.join(scratch, name)
    shutil.copytree(os.path.join(ROOT, "assets", "scenes"), work)
    scene = os.path.join(work, f"{name}.toml")
    study = os.path.join(work, "study")
    cmd = [vps, "run", "--scene", scene, "--seconds", seconds, "--study", study]
    subprocess.run(cmd, check=True, capture_output=True, env={**os.environ, "VPS_CACHE_DIR": os.path.join(work, "cache")})
    part = bvh(*load(os.path.join(study, "part.obj")))
    statics = [bvh(v, f) for v, f in placed_statics(scene)]
    with open(os.path.join(study, "path.csv")) as f:
        rows = list(csv.DictReader(f))
    poses = [
        (np.array([float(r[f"part_{k}_m"]) for k in "xyz"]), [float(r[f"part_q{k}"]) for k in "xyzw"])
        for r in rows
    ]
    summary = json.load(open(os.path.join(study, "study.json")))
    names = [o["name"] for o in summary["objects"]]
    t0 = time.time()
    fcl_all = np.array([[distance(part, pose, s) for s in statics] for pose in poses])
    fcl_s = time.time() - t0
    with open(os.path.join(study, "clearance.csv")) as f:
        series = list(csv.DictReader(f))
    diffs = []
    for r in series:
        i = int(r["frame"])
        for k, n in enumerate(names):
            diffs.append(abs(float(r[f"{n}_m"]) - fcl_all[i, k]))
    per_frame = fcl_all.min(axis=1)
    fcl_frame = int(np.argmin(per_frame))
    vps_min = summary["minimum_clearance"]
    return {
        "scene": f"assets/scenes/{name}.toml",
        "command": " ".join(["vps", "run", "--scene", f"assets/scenes/{name}.toml", "--seconds", seconds, "--study", "DIR"]),
        "frames": len(rows),
        "objects": names,
        "series_points_compared": len(diffs),
        "series_max_abs_difference_m": max(diffs),
        "vps_minimum_m": vps_min["distance_m"],
        "vps_minimum_frame": vps_min["frame"],
        "vps_minimum_object": vps_min["object"],
        "fcl_minimum_m": float(per_frame[fcl_frame]),
        "fcl_minimum_frame": fcl_frame,
        "fcl_minimum_object": names[int(np.argmin(fcl_all[fcl_frame]))],
        "minimum_abs_difference_m": abs(vps_min["distance_m"] - float(per_frame[fcl_frame])),
        "fcl_seconds_every_frame": round(fcl_s, 2),
        "vps_study_timings_ms": summary["timings_ms"],
        "verdict": summary["verdict"],
    }


def poses_of(path_csv):
    with open(path_csv) as f:
        rows = list(csv.DictReader(f))
    return [
        (np.array([float(r[f"part_{k}_m"]) for k in "xyz"]), [float(r[f"part_q{k}"]) for k in "xyzw"])
        for r in rows
    ]


def pair_distance(a, pose_a, b, pose_b):
    (pa, qa), (pb, qb) = pose_a, pose_b
    x = fcl.CollisionObject(a, fcl.Transform(np.array([qa[3], qa[0], qa[1], qa[2]]), pa))
    y = fcl.CollisionObject(b, fcl.Transform(np.array([qb[3], qb[0], qb[1], qb[2]]), pb))
    d = fcl.distance(x, y, fcl.DistanceRequest(enable_nearest_points=True), fcl.DistanceResult())
    return max(d, 0.0)


def study_pairs(vps, scratch):
    name, seconds = "two-hands", "5.4"
    work = os.path.join(scratch, name)
    shutil.copytree(os.path.join(ROOT, "assets", "scenes"), work)
    scene = os.path.join(work, f"{name}.toml")
    study = os.path.join(work, "study")
    cmd = [vps, "run", "--scene", scene, "--seconds", seconds, "--free-running", "--study", study]
    subprocess.run(cmd, check=True, capture_output=True, env={**os.environ, "VPS_CACHE_DIR": os.path.join(work, "cache")})
    pairs = json.load(open(os.path.join(study, "pairs.json")))
    a_name, b_name = pairs["parts"][0], pairs["parts"][1]
    a = bvh(*load(os.path.join(study, a_name, "part.obj")))
    b = bvh(*load(os.path.join(study, b_name, "part.obj")))
    pa = poses_of(os.path.join(study, a_name, "path.csv"))
    pb = poses_of(os.path.join(study, b_name, "path.csv"))
    t0 = time.time()
    every = np.array([pair_distance(a, x, b, y) for x, y in zip(pa, pb)])
    fcl_s = time.time() - t0
    with open(os.path.join(study, "pair_clearance.csv")) as f:
        series = list(csv.DictReader(f))
    column = f"{a_name}-{b_name}_m"
    diffs = [abs(float(r[column]) - every[int(r["frame"])]) for r in series]
    fcl_frame = int(np.argmin(every))
    vps_min = pairs["pairs"][0]
    return {
        "scene": f"assets/scenes/{name}.toml",
        "command": f"vps run --scene assets/scenes/{name}.toml --seconds {seconds} --free-running --study DIR",
        "parts": [a_name, b_name],
        "frames": len(pa),
        "series_points_compared": len(diffs),
        "series_max_abs_difference_m": max(diffs),
        "vps_minimum_m": vps_min["least_m"],
        "vps_minimum_frame": vps_min["frame"],
        "fcl_minimum_m": float(every[fcl_frame]),
        "fcl_minimum_frame": fcl_frame,
        "minimum_abs_difference_m": abs(vps_min["least_m"] - float(every[fcl_frame])),
        "fcl_seconds_every_frame": round(fcl_s, 2),
    }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--vps", default=os.path.join(ROOT, "target", "release", "vps"))
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        results = [study_scene(os.path.abspath(args.vps), n, s, scratch) for n, s in SCENES]
        pair = study_pairs(os.path.abspath(args.vps), scratch)
    out = {
        "reference": f"python-fcl {getattr(fcl, '__version__', '?')} (FCL mesh-mesh distance), trimesh {trimesh.__version__}",
        "command": "python3 docs/validation/study_clearance.py",
        "scenes": results,
        "pairs": [pair],
    }
    res = os.path.join(ROOT, "docs", "results")
    with open(os.path.join(res, "study_clearance.json"), "w") as f:
        json.dump(out, f, indent=1)
        f.write("\n")
    lines = [
        "# Study clearance against FCL",
        "",
        f"Made by `{out['command']}` (reference: {out['reference']}).",
        "",
        "| scene | frames | series points | series max \\|vps − FCL\\| | vps minimum (frame, object) | FCL minimum over every frame (frame, object) | \\|difference\\| |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in results:
        lines.append(
            f"| {r['scene']} | {r['frames']} | {r['series_points_compared']} | {r['series_max_abs_difference_m']:.2e} m "
            f"| {r['vps_minimum_m'] * 1e3:.6f} mm ({r['vps_minimum_frame']}, {r['vps_minimum_object']}) "
            f"| {r['fcl_minimum_m'] * 1e3:.6f} mm ({r['fcl_minimum_frame']}, {r['fcl_minimum_object']}) "
            f"| {r['minimum_abs_difference_m']:.2e} m |"
        )
    lines += [
        "",
        "Between two moving parts (each posed by its own path; vps measures the second in the first's frame):",
        "",
        "| scene | parts | frames | series points | series max \\|vps − FCL\\| | vps minimum (frame) | FCL minimum over every frame (frame) | \\|difference\\| |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in out["pairs"]:
        lines.append(
            f"| {r['scene']} | {' – '.join(r['parts'])} | {r['frames']} | {r['series_points_compared']} "
            f"| {r['series_max_abs_difference_m']:.2e} m | {r['vps_minimum_m'] * 1e3:.6f} mm ({r['vps_minimum_frame']}) "
            f"| {r['fcl_minimum_m'] * 1e3:.6f} mm ({r['fcl_minimum_frame']}) | {r['minimum_abs_difference_m']:.2e} m |"
        )
    lines.append("")
    with open(os.path.join(res, "study_clearance.md"), "w") as f:
        f.write("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
