#!/usr/bin/env python3
"""Runs issue 36's item tests (hostile input, round three) against an old and this tree's vps.

    python3 tests/hostile_old_vs_new.py --old /work/old-vps --old-commit 6860cd7 \
        --out docs/results/hostile-old-vs-new.json

The tests are the root package's integration tests, which run the real binary. The old run sets
`VPS_TEST_BINARY=OLD` (vps_testkit::process::vps_binary), so the same compiled test runs against
the old binary; the new run leaves it unset, so the test runs against the binary cargo built from
this tree. OLD is the `vps` of the commit before the round's first fix (6860cd7, the parent of
922848c), built in the test profile as cargo test builds this tree's:

    git worktree add --detach /work/wt-old 6860cd7
    (cd /work/wt-old && CARGO_TARGET_DIR=$PWD/../wt-hostile4/target \
        cargo build --profile test --bin vps) && cp target/debug/vps /work/old-vps

Each test runs alone (its test binary from `cargo test --no-run`, `--exact NAME`, run from the
package root as cargo test runs it) under a timeout; the
record holds whether it passed, the seconds, and the first lines of its panic message. Items
whose evidence is a unit test inside a crate (it cannot run against a binary) are listed with
`through_binary: false` and not run. Standard library only.
"""

import argparse
import json
import os
import re
import signal
import subprocess
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# (item, test file, test name, what the test asserts)
CASES = [
    (1, "scene", "another_scenes_map_copied_over_a_cache_entry_is_rebuilt_saying_why",
     "another scene's map copied over a cache entry is rebuilt, stderr saying why"),
    (2, "hostile_output", "an_output_that_is_a_fifo_a_device_or_a_link_to_one_is_refused_and_left_alone",
     "--report/--record/--log-wrenches/-o to a FIFO, device or link to one: exit 1, node untouched"),
    (3, "hostile_output", "an_output_equal_to_an_input_or_another_output_is_refused_before_any_work",
     "an output naming an input or another output: exit 1 before any work, inputs intact"),
    (4, "safe_stop", "no_wrench_sent_exceeds_the_device_limits_by_an_ulp",
     "every bridge wrench |F| <= max_force, |T| <= max_torque, exactly"),
    (5, "worker_service", "a_worker_restarted_at_once_after_a_crash_replaces_its_dead_connection",
     "a worker SIGKILLed and restarted at once with its certificate joins and stays"),
    (6, "hostile_output", "scenes_that_would_take_unbounded_memory_are_refused_before_it_is_taken",
     "21 MiB of empty arrays and 10,000 statics naming the bay refused before the memory is taken"),
    (6, "scene_memory", "deep_nesting_and_token_floods_are_refused_before_parsing_in_bounded_memory",
     "nesting 100,000 deep and 60 MiB of commas refused before parsing naming file, limit, line;"
     " peak RSS < 240 MiB"),
    (6, "scene_memory", "a_mesh_named_by_twenty_objects_is_read_once_and_not_copied",
     "one OBJ named 20 times is read once; peak RSS grows by < 4 copies"),
    (6, "scene_memory", "the_whole_scene_estimate_is_printed_and_refused_over_max_memory",
     "scene check prints the whole-scene estimate; scene check and run refuse over --max-memory"),
    (6, "scene_memory", "view_refuses_a_scene_over_max_memory_before_building_it",
     "vps view --scene ... --max-memory 64MiB refused naming the budget"),
    (7, "scene", "scene_check_refuses_what_a_session_would_naming_the_file_and_key",
     "grip 1e300, waypoint 1e308, speed 1e-300: scene check and run refuse naming file and key"),
    (8, "hostile_output", "control_characters_from_a_scene_file_are_printed_escaped",
     "ESC, BEL, CR from name / voxels.reason / a source never reach the terminal"),
    (9, "safe_stop", "a_sender_restarting_its_sequence_is_taken_back_after_the_pose_timeout",
     "a client restarting its sequence after u64::MAX gets forces again after the pose timeout"),
    (10, "hostile_output", "a_deeply_nested_scene_and_a_cache_that_is_a_file_get_short_clear_messages",
     "depth-100,000 nesting: short error; VPS_CACHE_DIR a file: says so, session runs"),
    (10, "hostile_output", "an_absurd_corridor_spacing_is_refused_with_a_short_count",
     "corridor.spacing = 1e-300: the count in scientific notation, a short message"),
    (10, "bounds", "a_coordinators_worker_count_is_bounded_by_the_classes",
     "workers = 1000000 (config or --workers) refused at once"),
]

# Evidence that cannot run against another binary: unit tests compiled into a crate.
UNIT_ONLY = [
    (1, "vps-session cache::tests::another_map_in_an_entry_is_not_used"),
    (4, "vps-device norm::tests::* (10^6 random vectors checked without rounding)"),
    (6, "vps-session file::tests::a_file_of_millions_of_arrays_is_refused_before_parsing"),
    (6, "vps-session file::tests::deep_nesting_and_too_many_tokens_are_refused_before_parsing_naming_the_line"),
    (10, "vps-session file::tests::absurd_positions_and_spacings_are_refused_with_short_messages"),
    (10, "vps-session cache::tests::a_cache_directory_that_is_a_file_says_so"),
]


def panic_message(output):
    """The lines of the first panic: from `panicked at` to the blank line or `note:`."""
    lines = output.splitlines()
    for i, line in enumerate(lines):
        if "panicked at" in line:
            body = []
            for l in lines[i + 1:]:
                if l.startswith("note:") or l.startswith("failures:") or l.strip() == "":
                    break
                body.append(l)
            text = "\n".join(body)
            # Cut long messages (an echoed scene line can be 600 KB) to their head and length.
            if len(text) > 1200:
                text = text[:1200] + f" ... ({len(text) - 1200} more characters)"
            return line.strip() + "\n" + text
    return None


def test_executables(files):
    """Builds the test binaries of `files` and returns {file: executable path}."""
    argv = ["cargo", "test", "-q", "-p", "vps", "--no-run", "--message-format=json"]
    for f in files:
        argv += ["--test", f]
    out = subprocess.run(argv, check=True, capture_output=True, text=True, cwd=ROOT).stdout
    paths = {}
    for line in out.splitlines():
        msg = json.loads(line)
        target = msg.get("target", {})
        if msg.get("reason") == "compiler-artifact" and target.get("kind") == ["test"] \
                and msg.get("executable"):
            paths[target["name"]] = msg["executable"]
    return paths


def run_test(executable, name, binary, timeout):
    """Runs test `name` of `executable` alone, against `binary` (None: the one cargo built)."""
    env = dict(os.environ)
    env.pop("VPS_TEST_BINARY", None)
    if binary:
        env["VPS_TEST_BINARY"] = binary
    # cargo test runs test binaries in the package root, where the tests expect to be.
    argv = [executable, "--exact", name, "--test-threads", "1", "--nocapture"]
    start = time.monotonic()
    p = subprocess.Popen(argv, env=env, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                         start_new_session=True)
    try:
        out, _ = p.communicate(timeout=timeout)
        timed_out = False
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        out, _ = p.communicate()
        timed_out = True
    text = out.decode("utf-8", "replace")
    ran = re.search(r"test result: \w+\. (\d+) passed; (\d+) failed", text)
    passed = bool(ran) and ran.group(1) == "1" and ran.group(2) == "0"
    failed = bool(ran) and ran.group(2) == "1"
    return {
        "outcome": "timed out" if timed_out else "passed" if passed else
        "failed" if failed else "did not run",
        "seconds": round(time.monotonic() - start, 1),
        "message": None if passed else (panic_message(text) or text[-1500:]),
        "binary_substituted": ("VPS_TEST_BINARY: testing" in text) if binary else None,
    }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--old", required=True, help="the old vps binary")
    ap.add_argument("--old-commit", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--timeout", type=float, default=600)
    ap.add_argument("--only", help="run only tests whose name contains this")
    args = ap.parse_args()
    new_commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, cwd=ROOT).stdout.strip()
    # Build every test binary first; the tests then run as cargo test runs them (the package
    # root as working directory), without cargo, so no test's time includes compiling.
    exes = test_executables(sorted({f for _, f, _, _ in CASES}))
    rows = []
    for item, test_file, name, what in CASES:
        if args.only and args.only not in name:
            continue
        old = run_test(exes[test_file], name, os.path.abspath(args.old), args.timeout)
        new = run_test(exes[test_file], name, None, args.timeout)
        row = {"item": item, "test": f"{test_file}::{name}", "asserts": what,
               "old": old, "new": new}
        rows.append(row)
        print(f"item {item:2} {test_file}::{name}: old {old['outcome']}, new {new['outcome']}",
              flush=True)
    doc = {
        "what": "issue 36 item tests through the binary, run against the old and the new vps",
        "old_commit": args.old_commit,
        "new_commit": new_commit + " (with this branch's working tree)",
        "profile": "test (opt-level 2), both binaries",
        "command": "python3 tests/hostile_old_vs_new.py --old OLD_VPS --old-commit "
                   f"{args.old_commit} --out {args.out}",
        "rows": rows,
        "unit_tests_not_run_against_a_binary": [
            {"item": i, "test": t} for i, t in UNIT_ONLY
        ],
    }
    with open(args.out, "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
