#!/usr/bin/env python3
"""Re-runs the nine findings of the safe-stop and hostile-input audit against two vps binaries.

    python3 tests/findings_old_vs_new.py --old OLD/vps --new target/release/vps \
        --fuzz target/release/vps-fuzz --out docs/results/findings-old-vs-new.json

OLD is the release binary of the commit the findings were filed against (cd2871a), NEW today's.
Each case runs the finding's command the same way against both and records the exit status (or
the signal that ended the process), whether a panic or an allocation abort was printed, the wall
time and a one-line outcome, plus `reproduces` (true when the finding still shows). Processes run
with an address-space limit (RLIMIT_AS, 4 GiB unless a case says otherwise) and a timeout, so a
finding that grows without bound ends in an allocation abort instead of taking the machine.
`--fuzz` is the vps-fuzz binary, used only to write the crafted 2^39-voxel map.

Finding 8 (the same worker certificate joining twice) is fixed by the cluster change; its case is
here and marked so. Standard library only (socket, struct, subprocess, resource).
"""

import argparse
import json
import math
import os
import resource
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time

GIB = 1 << 30
POSE_IN = struct.Struct("<4sBB16sQ13d")  # kind 1, understood by both binaries
WRENCH_OUT = struct.Struct("<4sBB16sQ6dQ")
BAY_START = (0.05, 1.0, 0.75)  # the first point of the built-in bay's corridor (m)


def limits(mem_bytes):
    def apply():
        if mem_bytes:
            resource.setrlimit(resource.RLIMIT_AS, (mem_bytes, mem_bytes))
        os.setsid()

    return apply


class Proc:
    """A vps process whose stderr is collected by a thread."""

    def __init__(self, argv, cwd, env, mem=4 * GIB, stdout=subprocess.DEVNULL):
        self.argv = argv
        self.start = time.monotonic()
        self.p = subprocess.Popen(
            argv,
            cwd=cwd,
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=stdout,
            stderr=subprocess.PIPE,
            preexec_fn=limits(mem),
        )
        self.lines = []
        self.t = threading.Thread(target=self._drain, daemon=True)
        self.t.start()

    def _drain(self):
        for raw in self.p.stderr:
            self.lines.append(raw.decode("utf-8", "replace").rstrip("\n"))

    def wait_line(self, prefix, timeout):
        until = time.monotonic() + timeout
        while time.monotonic() < until:
            for line in list(self.lines):
                if prefix in line:
                    return line
            if self.p.poll() is not None:
                time.sleep(0.1)
                return next((l for l in self.lines if prefix in l), None)
            time.sleep(0.02)
        return None

    def wait_or_kill(self, timeout):
        """Waits up to `timeout` s for the process; kills its group past that. True if killed."""
        try:
            self.p.wait(timeout)
            return False
        except subprocess.TimeoutExpired:
            os.killpg(self.p.pid, signal.SIGKILL)
            self.p.wait()
            return True

    def wait(self, timeout):
        timed_out = self.wait_or_kill(timeout)
        self.t.join(2)
        return result(self, timed_out)

    def kill(self):
        if self.p.poll() is None:
            os.killpg(self.p.pid, signal.SIGKILL)
            self.p.wait()


def result(proc, timed_out=False, stdout=b""):
    rc = proc.p.returncode
    err = "\n".join(proc.lines)
    return {
        "argv": [os.path.basename(proc.argv[0])] + proc.argv[1:],
        "exit": rc if rc is not None and rc >= 0 else None,
        "signal": signal.Signals(-rc).name if rc is not None and rc < 0 else None,
        "timed_out": timed_out,
        "panicked": "panicked" in err,
        "allocation_abort": "memory allocation of" in err,
        "seconds": round(time.monotonic() - proc.start, 3),
        "stderr_tail": err[-2000:],
        "stdout_head": stdout[:300].decode("utf-8", "replace"),
    }


def run(vps, args, cwd, env, timeout=60, mem=4 * GIB, stdout=subprocess.PIPE):
    proc = Proc([vps] + args, cwd, env, mem, stdout=stdout)
    chunks = []
    reader = None
    if stdout == subprocess.PIPE:
        reader = threading.Thread(target=lambda: chunks.append(proc.p.stdout.read()), daemon=True)
        reader.start()
    timed_out = proc.wait_or_kill(timeout)
    if reader:
        reader.join(5)
    proc.t.join(5)
    return result(proc, timed_out, b"".join(chunks))


def failed_cleanly(r):
    """A non-zero exit with a message: no panic, no abort, no signal, no timeout."""
    return (
        r["exit"] not in (None, 0)
        and not r["panicked"]
        and not r["allocation_abort"]
        and not r["timed_out"]
        and r["stderr_tail"].strip() != ""
    )


# ---------------------------------------------------------------------------------------------
# Finding 1: SIGINT/SIGTERM with a client pressing on a wall.


def pose(seq, position):
    values = list(position) + [0.0, 0.0, 0.0, 1.0] + [0.0] * 6
    return POSE_IN.pack(b"VPSB", 1, 1, bytes(16), seq, *values)


def wrench(data):
    if len(data) != WRENCH_OUT.size:
        return None
    magic, version, kind, _tok, _seq, *rest = WRENCH_OUT.unpack(data)
    if magic != b"VPSB" or kind != 2:
        return None
    return rest[:6]


def bridge_socket(addr):
    """A non-blocking UDP socket connected to the session's bridge address."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.connect(addr)
    s.setblocking(False)
    return s


def send_pose(s, seq, position):
    """Sends pose datagram `seq` at `position` (a refused send is ignored), then waits 1 ms."""
    try:
        s.send(pose(seq, position))
    except OSError:
        pass
    time.sleep(0.001)


def received_wrenches(s):
    """Every wrench datagram waiting on the non-blocking socket `s`, oldest first."""
    out = []
    while True:
        try:
            w = wrench(s.recv(128))
        except OSError:
            return out
        if w:
            out.append(w)


def bridge_session(vps, cwd, env, seconds, report):
    args = ["run", "--device", "bridge:127.0.0.1:0", "--seconds", str(seconds)]
    if report:
        args += ["--report", report]
    proc = Proc([vps] + args, cwd, env)
    line = proc.wait_line("device bridge listening on ", 120)
    if line is None:
        return proc, None, args
    host, port = line.split("listening on ")[1].strip().rsplit(":", 1)
    return proc, (host, int(port)), args


def press_then_signal(vps, cwd, env, sig, report_flag):
    report = os.path.join(cwd, "report-%s.json" % sig)
    proc, addr, args = bridge_session(vps, cwd, env, 600, report if report_flag else None)
    if addr is None:
        r = proc.wait(5)
        r["outcome"] = "no bridge address on stderr"
        return r
    s = bridge_socket(addr)
    pressed = (BAY_START[0], BAY_START[1], BAY_START[2] - 1.0)
    seq = 0
    in_contact = 0
    last = None
    until = time.monotonic() + 120
    while in_contact < 200 and time.monotonic() < until:
        seq += 1
        send_pose(s, seq, pressed)
        for w in received_wrenches(s):
            last = w
            in_contact = in_contact + 1 if math.sqrt(sum(f * f for f in w[:3])) > 0.1 else 0
    pressed_force = last
    os.kill(proc.p.pid, getattr(signal, "SIG" + sig))
    killed_at = time.monotonic()
    while proc.p.poll() is None and time.monotonic() < killed_at + 60:
        seq += 1
        send_pose(s, seq, pressed)
        last = (received_wrenches(s) or [last])[-1]
    time.sleep(0.3)
    last = (received_wrenches(s) or [last])[-1]
    r = proc.wait(5)
    r["exit_after_signal_s"] = round(time.monotonic() - killed_at, 3)
    r["argv"] = [os.path.basename(vps)] + args
    r["force_while_pressing_n"] = (
        math.sqrt(sum(f * f for f in pressed_force[:3])) if pressed_force else None
    )
    r["last_wrench_out"] = list(last) if last else None
    zero = last is not None and all(struct.pack("<d", v) == bytes(8) for v in last)
    r["last_wrench_exact_zero"] = zero
    r["report_written"] = os.path.exists(report)
    if r["report_written"]:
        with open(report) as f:
            rep = json.load(f)
        r["report_end"] = rep.get("end")
        r["report_complete"] = rep.get("complete")
    r["reproduces"] = not (zero and r["report_written"])
    r["outcome"] = "last WrenchOut %s after SIG%s, exit %s, report %s" % (
        "exactly zero" if zero else ("%s" % (last,)),
        sig,
        r["exit"],
        "written" if r["report_written"] else "absent",
    )
    return r


def run_help(vps, command, cwd, env):
    out = subprocess.run([vps, command, "--help"], cwd=cwd, env=env, capture_output=True)
    return out.stdout.decode("utf-8", "replace")


def finding1(vps, cwd, env):
    report_flag = "--report" in run_help(vps, "run", cwd, env)
    return {
        "sigterm": press_then_signal(vps, cwd, env, "TERM", report_flag),
        "sigint": press_then_signal(vps, cwd, env, "INT", report_flag),
    }


# ---------------------------------------------------------------------------------------------
# Finding 2: vps view of a crafted 16 KiB map of 2^39 voxels.


def finding2(vps, cwd, env, huge):
    proc = Proc([vps, "view", huge, "--addr", "127.0.0.1:0"], cwd, env)
    line = proc.wait_line("viewer: ", 120)
    served = None
    if line is not None:
        url = line.split("viewer: ")[1].split()[0]
        host, port = url.split("//")[1].strip("/").rsplit(":", 1)
        served = http_get(host, int(port), "/scene", host + ":" + port)
    proc.kill() if line is not None else None
    r = proc.wait(30)
    r["http_scene_status"] = served
    r["reproduces"] = served != 200
    r["outcome"] = (
        "served /scene with %s" % served
        if served
        else "no server: %s" % (r["signal"] or "exit %s" % r["exit"])
    )
    return r


def http_get(host, port, path, host_header, origin=None, upgrade=False):
    """The status code of one request, or None when the connection failed."""
    try:
        with socket.create_connection((host, port), timeout=10) as c:
            req = "GET %s HTTP/1.1\r\nHost: %s\r\n" % (path, host_header)
            if not upgrade:
                req += "Connection: close\r\n"
            if origin:
                req += "Origin: %s\r\n" % origin
            if upgrade:
                req += (
                    "Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\n"
                    "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                )
            c.sendall((req + "\r\n").encode())
            data = c.recv(64)
            return int(data.split(b" ")[1])
    except (OSError, ValueError, IndexError):
        return None


# ---------------------------------------------------------------------------------------------
# Finding 3: the 12-triangle 10 m cube at 1 mm.


def cube_obj(path, size):
    h = size / 2
    v = [(x, y, z) for x in (-h, h) for y in (-h, h) for z in (-h, h)]
    f = [(1, 3, 4), (1, 4, 2), (5, 6, 8), (5, 8, 7), (1, 2, 6), (1, 6, 5),
         (3, 7, 8), (3, 8, 4), (1, 5, 7), (1, 7, 3), (2, 4, 8), (2, 8, 6)]
    with open(path, "w") as out:
        for p in v:
            out.write("v %g %g %g\n" % p)
        for t in f:
            out.write("f %d %d %d\n" % t)


def finding3(vps, cwd, env):
    cube = os.path.join(cwd, "cube10m.obj")
    cube_obj(cube, 10.0)
    r = run(vps, ["voxelize", cube, "--voxel-size", "1mm", "-o", os.path.join(cwd, "c.vmap")],
            cwd, env, timeout=60, mem=3 * GIB)
    r["reproduces"] = not (failed_cleanly(r) and "memory" in r["stderr_tail"])
    r["outcome"] = outcome(r)
    return r


def outcome(r):
    if r["timed_out"]:
        return "still running at the timeout (killed)"
    if r["allocation_abort"]:
        return "allocation abort (%s)" % (r["signal"] or r["exit"])
    if r["panicked"]:
        return "panic (exit %s)" % r["exit"]
    if r["signal"]:
        return "killed by %s" % r["signal"]
    if r["exit"] == 0:
        return "exit 0"
    lines = [l for l in r["stderr_tail"].splitlines() if l.strip()]
    errors = [l for l in lines if "error" in l]
    line = (errors or lines or [""])[0]
    return "exit %s: %s" % (r["exit"], line[:240])


# ---------------------------------------------------------------------------------------------
# Finding 4: a scene's corridor crashes tune and sweep.


def rig_with(root, cwd, name, old, new):
    text = open(os.path.join(root, "configs/scenes/rig-teapot.toml")).read()
    assert old in text
    path = os.path.join(cwd, name)
    with open(path, "w") as f:
        f.write(text.replace(old, new))
    return path


def finding4(vps, cwd, env, root):
    cases = {}
    for key, old, new in [
        ("spacing_1e-300", "spacing = 0.025", "spacing = 1e-300"),
        ("spacing_1e-12", "spacing = 0.025", "spacing = 1e-12"),
        ("to_1e6", "to = [0.35, 0.0, 0.0]", "to = [1e6, 0.0, 0.0]"),
    ]:
        scene = rig_with(root, cwd, key + ".toml", old, new)
        if key == "to_1e6":
            # The workspace would refuse the far end first; without it the corridor is what counts.
            text = open(scene).read().split("[workspace]")[0]
            open(scene, "w").write(text)
        r = run(vps, ["tune", "--scene", scene, "--frames", "100", "--verify-frames", "100"],
                cwd, env, timeout=90, mem=3 * GIB)
        r["reproduces"] = not (failed_cleanly(r) and "corridor" in r["stderr_tail"])
        r["outcome"] = outcome(r)
        cases["tune_" + key] = r
    return cases


# ---------------------------------------------------------------------------------------------
# Finding 5: broken pipe, full disk, output paths.


def small_map(vps, cwd, env):
    path = os.path.join(cwd, "small.vmap")
    if not os.path.exists(path):
        subprocess.run([vps, "voxelize", "builtin:sphere", "--voxel-size", "1cm", "-o", path],
                       cwd=cwd, env=env, capture_output=True)
    return path


def closed_stdout(vps, args, cwd, env):
    r_fd, w_fd = os.pipe()
    os.close(r_fd)
    proc = Proc([vps] + args, cwd, env, stdout=w_fd)
    os.close(w_fd)
    r = proc.wait(60)
    r["reproduces"] = r["panicked"] or r["exit"] not in (141,) and r["signal"] != "SIGPIPE"
    r["outcome"] = outcome(r)
    return r


def finding5(vps, cwd, env):
    m = small_map(vps, cwd, env)
    points = os.path.join(cwd, "big.csv")
    with open(points, "w") as f:
        f.write("0,0,0\n" * 20000)
    cases = {
        "probe_points_closed_stdout": closed_stdout(vps, ["probe", m, "--points", points], cwd, env),
        "inspect_json_closed_stdout": closed_stdout(vps, ["inspect", m, "--json"], cwd, env),
        "devices_closed_stdout": closed_stdout(vps, ["devices"], cwd, env),
    }
    with open("/dev/full", "w") as full:
        r = run(vps, ["run", "--seconds", "1", "--json"], cwd, env, timeout=120, stdout=full)
    r["reproduces"] = not (failed_cleanly(r) and "stdout" in r["stderr_tail"])
    r["outcome"] = outcome(r)
    cases["run_json_to_dev_full"] = r
    mesh = os.path.join(cwd, "tetra.obj")
    text = "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0 0 0.1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
    with open(mesh, "w") as f:
        f.write(text)
    r = run(vps, ["voxelize", mesh, "--voxel-size", "1cm", "-o", mesh], cwd, env)
    with open(mesh, "rb") as f:
        kept = f.read() == text.encode()
    r["input_kept"] = kept
    r["reproduces"] = not (kept and failed_cleanly(r))
    r["outcome"] = outcome(r) + ("; mesh kept" if kept else "; mesh overwritten")
    cases["voxelize_output_is_the_input"] = r
    r = run(vps, ["run", "--seconds", "2", "--record", "/nonexistent/dir/t.trace"], cwd, env,
            timeout=120)
    r["reproduces"] = not (failed_cleanly(r) and r["seconds"] < 1.5)
    r["outcome"] = outcome(r) + " after %.2f s" % r["seconds"]
    cases["run_record_bad_path"] = r
    return cases


# ---------------------------------------------------------------------------------------------
# Finding 6: bounds on what the user names.


def finding6(vps, cwd, env, root):
    cases = {}
    for key, args in [
        ("run_threads_10000", ["run", "--threads", "10000", "--seconds", "0.2"]),
        ("run_seconds_-1", ["run", "--seconds=-1"]),
        ("run_seconds_nan", ["run", "--seconds=nan"]),
        ("cluster_local_workers_1000", ["cluster", "--local-workers", "1000", "--seconds", "0.1"]),
    ]:
        # Thread stacks need address space: no RLIMIT_AS here, a timeout instead.
        r = run(vps, args, cwd, env, timeout=60, mem=None)
        r["reproduces"] = not failed_cleanly(r)
        r["outcome"] = outcome(r)
        cases[key] = r
    haptic = os.path.join(cwd, "weak.toml")
    with open(haptic, "w") as f:
        f.write("k_ff = 1e-300\n")
    r = run(vps, ["run", "--seconds", "0.2", "--config", haptic], cwd, env)
    r["reproduces"] = not (failed_cleanly(r) and "k_ff" in r["stderr_tail"])
    r["outcome"] = outcome(r)
    cases["run_k_ff_1e-300"] = r
    rig = os.path.join(root, "configs/scenes/rig-teapot.toml")
    for key, body in [
        ("sweep_voxel_sizes_empty", 'voxel_sizes_mm = []\nmethods = ["centres"]\n'
                                    '[[run]]\nscene = "%s"\n' % rig),
        ("sweep_seconds_-1", 'voxel_sizes_mm = [10.0]\nmethods = ["centres"]\n'
                             '[[run]]\nscene = "%s"\nseconds = -1\n' % rig),
    ]:
        cfg = os.path.join(cwd, key + ".toml")
        with open(cfg, "w") as f:
            f.write(body)
        r = run(vps, ["sweep", "--quick", "--config", cfg, "--json",
                      os.path.join(cwd, key + ".json")], cwd, env, timeout=120)
        r["reproduces"] = not failed_cleanly(r)
        r["outcome"] = outcome(r)
        cases[key] = r
    return cases


# ---------------------------------------------------------------------------------------------
# Finding 7: the viewer.


def finding7(vps, cwd, env):
    m = small_map(vps, cwd, env)
    cases = {}
    proc = Proc([vps, "view", m, "--addr", "0.0.0.0:0"], cwd, env)
    line = proc.wait_line("viewer: ", 60) or ""
    proc.kill()
    r = proc.wait(10)
    r["printed"] = line
    r["reproduces"] = "127.0.0.1" in line
    r["outcome"] = "printed %r" % line
    cases["view_addr_0000_prints"] = r

    proc = Proc([vps, "view", m, "--addr", "127.0.0.1:0"], cwd, env)
    line = proc.wait_line("viewer: ", 60)
    port = int(line.split("viewer: ")[1].split()[0].strip("/").rsplit(":", 1)[1]) if line else 0
    here = "127.0.0.1:%d" % port
    foreign_ws = http_get("127.0.0.1", port, "/ws", here, origin="http://evil.example", upgrade=True)
    foreign_host = http_get("127.0.0.1", port, "/state", "evil.example:%d" % port)
    own_ws = http_get("127.0.0.1", port, "/ws", here, origin="http://" + here, upgrade=True)
    # 48 slow half-requests: how many are still open 12 s later (the new header timeout is 10 s).
    slow = []
    for _ in range(48):
        try:
            c = socket.create_connection(("127.0.0.1", port), timeout=5)
            c.sendall(b"GET / HTTP/1.1\r\nHost: " + here.encode() + b"\r\n")
            slow.append(c)
        except OSError:
            pass
    time.sleep(12)
    still_open = 0
    for c in slow:
        # Closed: EOF (after whatever the server sent, e.g. a 408) or a reset. Open: no EOF yet.
        c.settimeout(0.2)
        try:
            while c.recv(4096):
                pass
        except socket.timeout:
            still_open += 1
        except OSError:
            pass
        c.close()
    proc.kill()
    r = proc.wait(10)
    r.update(
        foreign_origin_ws_status=foreign_ws,
        foreign_host_status=foreign_host,
        own_origin_ws_status=own_ws,
        slow_half_requests=len(slow),
        slow_still_open_after_12s=still_open,
    )
    r["reproduces"] = foreign_ws == 101 or foreign_host == 200 or still_open > 0
    r["outcome"] = "foreign Origin ws %s, foreign Host %s, own Origin ws %s, %d/%d slow open" % (
        foreign_ws, foreign_host, own_ws, still_open, len(slow))
    cases["view_origin_host_slow_headers"] = r
    return cases


# ---------------------------------------------------------------------------------------------
# Finding 8: the same worker certificate joining twice (fixed by the cluster change).


def finding8(vps, cwd, env):
    for name in ("coordinator", "worker", "stranger"):
        subprocess.run([vps, "cert", "--out", cwd, "--name", name], cwd=cwd, env=env,
                       capture_output=True)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    p = lambda n: os.path.join(cwd, n)
    envl = dict(env, RUST_LOG="vps_cluster=info")
    coord = Proc([vps, "coordinator", "--listen", "127.0.0.1:%d" % port, "--cert",
                  p("coordinator.crt"), "--key", p("coordinator.key"), "--pin", p("worker.crt"),
                  "--workers", "1", "--seconds", "30"], cwd, envl)

    def worker(name):
        return Proc([vps, "worker", "--coordinator", "127.0.0.1:%d" % port, "--cert",
                     p(name + ".crt"), "--key", p(name + ".key"), "--pin", p("coordinator.crt"),
                     "--threads", "1"], cwd, envl)

    first = worker("worker")
    time.sleep(8)
    second = worker("worker")
    time.sleep(6)
    second_alive = second.p.poll() is None
    stranger = worker("stranger")
    stranger_r = stranger.wait(20)
    second.kill()
    second_r = second.wait(5)
    first.kill()
    coord.kill()
    coord_r = coord.wait(5)
    first.wait(5)
    r = {
        "second_same_cert": second_r,
        "second_same_cert_still_connected_after_6s": second_alive,
        "unpinned_worker": stranger_r,
        "coordinator_stderr_tail": coord_r["stderr_tail"],
        "note": "fixed by the cluster change (one live connection per pinned identity)",
    }
    r["reproduces"] = second_alive or "connection lost" in stranger_r["stderr_tail"]
    r["outcome"] = "second join with the same certificate %s; unpinned worker: %s" % (
        "stayed connected" if second_alive else "ended (%s)" % outcome(second_r),
        outcome(stranger_r),
    )
    return r


# ---------------------------------------------------------------------------------------------
# Finding 9: reports and messages.


def finding9(vps, cwd, env, root):
    cases = {}
    report_flag = "--report" in run_help(vps, "run", cwd, env)
    report = os.path.join(cwd, "rejected.json")
    proc, addr, args = bridge_session(vps, cwd, env, 2, report if report_flag else None)
    args = args + ["--json"]
    if addr is not None:
        s = bridge_socket(addr)
        seq = 0
        until = time.monotonic() + 60
        while proc.p.poll() is None and time.monotonic() < until:
            seq += 1
            send_pose(s, seq, (1.0e4, 0.0, 0.0))  # 10 km away: rejected by the core
    r = proc.wait(30)
    stats = {}
    if os.path.exists(report):
        with open(report) as f:
            rep = json.load(f)
        stats = rep.get("stats", {})
        r["report_end"] = rep.get("end")
        r["report_keys"] = sorted(rep.keys())
    r["rejected_input_frames"] = stats.get("rejected_input_frames")
    r["zeroed_frames"] = stats.get("zeroed_frames")
    r["reproduces"] = not (r["rejected_input_frames"] or 0) > 0
    r["outcome"] = "exit %s; report %s; rejected_input_frames %s" % (
        r["exit"], "written" if os.path.exists(report) else "absent", r["rejected_input_frames"])
    cases["rejected_samples_counted"] = r

    slow = os.path.join(cwd, "slow.toml")
    with open(slow, "w") as f:
        f.write("dt = 0.002\n")
    r = run(vps, ["run", "--seconds", "0.2", "--config", slow], cwd, env)
    r["reproduces"] = not (failed_cleanly(r) and "slow.toml" in r["stderr_tail"]
                           and "dt" in r["stderr_tail"])
    r["outcome"] = outcome(r)
    cases["dt_0.002_names_file_and_field"] = r

    scale = rig_with(root, cwd, "scale.toml", "scale = [5.0, 2.4, 0.4]", "scale = [0.0, 2.4, 0.4]")
    r = run(vps, ["tune", "--scene", scale, "--frames", "100", "--verify-frames", "100"], cwd, env)
    r["reproduces"] = not (failed_cleanly(r) and "static[0].scale" in r["stderr_tail"])
    r["outcome"] = outcome(r)
    cases["scene_scale_names_field"] = r

    empty = os.path.join(cwd, "empty.vmap")
    open(empty, "w").close()
    r = run(vps, ["inspect", empty], cwd, env)
    r["reproduces"] = "failed to fill whole buffer" in r["stderr_tail"] or not failed_cleanly(r)
    r["outcome"] = outcome(r)
    cases["inspect_empty_file"] = r

    r = run(vps, ["inspect", "/nonexistent/nope.vmap"], cwd, env)
    r["reproduces"] = r["stderr_tail"].count("No such file or directory") != 1
    r["outcome"] = outcome(r)
    cases["missing_file_cause_once"] = r
    return cases


# ---------------------------------------------------------------------------------------------


def flatten_reproduces(value):
    if isinstance(value, dict):
        if "reproduces" in value:
            return [value["reproduces"]]
        return [x for v in value.values() for x in flatten_reproduces(v)]
    return []


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--old", required=True)
    ap.add_argument("--new", required=True)
    ap.add_argument("--fuzz", required=True, help="the vps-fuzz binary (writes the crafted map)")
    ap.add_argument("--out", required=True)
    ap.add_argument("--only", default="", help="comma-separated finding numbers (default: all)")
    a = ap.parse_args()
    only = {int(x) for x in a.only.split(",") if x}
    results = {}
    for label, vps in (("old", os.path.abspath(a.old)), ("new", os.path.abspath(a.new))):
        # The checkout the binary was built in (its scene files match its format).
        root = os.path.dirname(os.path.dirname(os.path.dirname(vps)))
        work = tempfile.mkdtemp(prefix="vps-findings-%s-" % label)
        env = dict(os.environ, VPS_CACHE_DIR=os.path.join(work, "cache"), RUST_BACKTRACE="0")
        huge = os.path.join(work, "huge.vmap")
        if not only or 2 in only:
            subprocess.run([a.fuzz, "--write-huge-vmap", huge], check=True)
        cases = {
            1: lambda: finding1(vps, work, env),
            2: lambda: finding2(vps, work, env, huge),
            3: lambda: finding3(vps, work, env),
            4: lambda: finding4(vps, work, env, root),
            5: lambda: finding5(vps, work, env),
            6: lambda: finding6(vps, work, env, root),
            7: lambda: finding7(vps, work, env),
            8: lambda: finding8(vps, work, env),
            9: lambda: finding9(vps, work, env, root),
        }
        out = {}
        for n, case in cases.items():
            if only and n not in only:
                continue
            print("%s: finding %d" % (label, n), file=sys.stderr, flush=True)
            try:
                out[str(n)] = case()
            except Exception as e:  # a broken case is recorded, not fatal
                out[str(n)] = {"error": repr(e), "reproduces": None}
        results[label] = out
        shutil.rmtree(work, ignore_errors=True)
    summary = {}
    for n in sorted({k for r in results.values() for k in r}, key=int):
        summary[n] = {label: flatten_reproduces(results[label].get(n, {})) for label in results}
    doc = {
        "command": "python3 tests/findings_old_vs_new.py --old OLD --new NEW --fuzz FUZZ --out FILE",
        "old": os.path.abspath(a.old),
        "new": os.path.abspath(a.new),
        "summary_reproduces": summary,
        "results": results,
    }
    with open(a.out, "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")
    for n, s in summary.items():
        print("finding %s: old reproduces %s; new reproduces %s" % (n, s.get("old"), s.get("new")))


if __name__ == "__main__":
    main()
