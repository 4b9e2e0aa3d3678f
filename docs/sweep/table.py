#!/usr/bin/env python3
"""The table of docs/sweep.md from a sweep's JSON: `python3 docs/sweep/table.py docs/sweep/sweep.json`.

One markdown row per scene, force model, voxel size, width and method, in the sweep's order; a
figure the sweep did not measure (null) prints as "–".
"""
import json
import sys


def fmt(value, digits):
    if value is None:
        return "–"
    if value == 0:
        return "0"
    return f"{value:.{digits}f}"


def main(path):
    rows = json.load(open(path))["rows"]
    print(
        "| scene | model | method | s (mm) | bits | default | points | voxmap (MiB) | voxelize (ms) "
        "| p50 (µs) | p99.9 (µs) | PR | compared | dir err p50/p95 (°) | mag err p50 "
        "| \\|F_vox\\|/\\|F_ref\\| p50 | min sep (mm) |"
    )
    print("|---" * 17 + "|")
    for r in rows:
        default = ""
        if r["default"]:
            default = "**yes (size too)**" if r["default_size"] else "yes"
        pr = r["penetration_ratio"]
        pr = "–" if pr is None else ("0" if pr == 0 else f"{pr:.4f}")
        print(
            f"| {r['scene']} | {r.get('force_model', 'tangent-plane')} | {r['method']} "
            f"| {r['voxel_size_mm']:g} | {r['voxel_width']} | {default} | {r['shell_points']} "
            f"| {r['voxmap_bytes'] / 2**20:.2f} | {r['voxelize_ms']:.0f} | {r['compute_p50_us']:.1f} "
            f"| {r['compute_p999_us']:.0f} | {pr} | {r['compared_frames']} "
            f"| {fmt(r['direction_error_deg_p50'], 1)} / {fmt(r['direction_error_deg_p95'], 1)} "
            f"| {fmt(r['magnitude_error_p50'], 2)} | {fmt(r['magnitude_ratio_p50'], 2)} "
            f"| {fmt(r['min_separation_mm'], 2)} |"
        )


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "docs/sweep/sweep.json")
