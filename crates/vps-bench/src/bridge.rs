//! `vps bench bridge`: the device bridge's round trip (client pose sent → the wrench computed
//! after reading it received by the client) beside a raw UDP ping-pong, in the same run.
//!
//! Both bridge figures use the real [`BridgeDevice`] and [`BridgeClient`] over 127.0.0.1 in this
//! process (no scene: the device writes a constant wrench, so frame compute is not included):
//! - `bridge_immediate`: the device thread polls `read` without sleeping and writes as soon as a
//!   pose was accepted; the client sends one pose and waits for its wrench. Transport plus both
//!   codecs, comparable with the raw ping-pong.
//! - `bridge_paced_1khz`: what a 1 kHz device client sees from a 1 kHz session: the device thread
//!   reads and writes once per 1 ms frame, the client sends one pose per (1 + 1/n) ms on its own
//!   clock, so over the n round trips its phase against the frames sweeps once, uniformly, through
//!   a whole frame (as two unsynchronised 1 kHz clocks drift), and a pose's round trip ends at the first wrench written after the frame
//!   that accepted it (or a newer pose), timed when it arrives (the client polls between its
//!   ticks without sleeping). Adds up to one frame of phase; a real session adds its
//!   frame compute on top.
//!
//! Raw UDP: blocking sockets on 127.0.0.1, one echo thread, unpinned, pose-sized payload (138
//! bytes), as in `vps bench transport`.

use anyhow::{bail, Context, Result};
use glam::{DQuat, DVec3};
use serde::Serialize;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use vps_app::output::print_report;
use vps_device::HapticDevice;
use vps_haptic::{HandleSample, Wrench};
use vps_input::bridge::protocol::POSE_IN_FLAGS_LEN;
use vps_input::{BridgeClient, BridgeConfig, BridgeDevice};
use vps_netem::transport_bench::{
    percentiles, raw_udp_round_trips, TransportPercentiles, UdpPlacement,
};

/// How long the client waits for one reply before counting the round trip as lost.
const REPLY_TIMEOUT: Duration = Duration::from_millis(100);
const FRAME: Duration = Duration::from_millis(1);

/// One bridge measurement.
#[derive(Serialize)]
struct BridgeFigure {
    round_trips: usize,
    /// Poses without a reply (within 100 ms, or before the end of the run).
    lost: usize,
    #[serde(flatten)]
    percentiles: TransportPercentiles,
}

#[derive(Serialize)]
struct BridgeReport {
    host_idle: crate::machine::HostIdle,
    raw_udp: BridgeFigure,
    bridge_immediate: BridgeFigure,
    bridge_paced_1khz: BridgeFigure,
    immediate_p50_over_raw_udp_p50: f64,
    immediate_p999_over_raw_udp_p999: f64,
}

fn figure(times: &[Duration], lost: usize) -> BridgeFigure {
    BridgeFigure {
        round_trips: times.len(),
        lost,
        percentiles: percentiles(times),
    }
}

fn pose(k: u64) -> HandleSample {
    HandleSample {
        position: DVec3::new(1e-6 * k as f64, 0.0, 0.0),
        orientation: DQuat::IDENTITY,
        linear_velocity: DVec3::ZERO,
        angular_velocity: DVec3::ZERO,
    }
}

const WRENCH: Wrench = Wrench {
    force: DVec3::new(0.0, 0.0, 1.5),
    torque: DVec3::ZERO,
};

/// Binds a bridge that never times the client out (the bench measures transport, not holding).
fn bind() -> Result<BridgeDevice> {
    Ok(BridgeDevice::bind(BridgeConfig {
        pose_timeout: 10.0,
        ..Default::default()
    })?)
}

/// Runs `serve(device, stop)` on its own thread while `client(addr)` runs here.
fn with_device<T: Send + 'static, U>(
    serve: impl FnOnce(BridgeDevice, &AtomicBool) -> Result<T> + Send + 'static,
    client: impl FnOnce(std::net::SocketAddr) -> Result<U>,
) -> Result<(T, U)> {
    let device = bind()?;
    let addr = device.local_addr();
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let server = std::thread::spawn(move || serve(device, &flag));
    let measured = client(addr);
    stop.store(true, Ordering::Relaxed);
    let served = server
        .join()
        .map_err(|_| anyhow::anyhow!("the bridge thread panicked"))??;
    Ok((served, measured?))
}

fn immediate(n: usize) -> Result<BridgeFigure> {
    let ((), (times, lost)) = with_device(
        |mut device, stop| {
            let start = Instant::now();
            let mut replied = 0;
            while !stop.load(Ordering::Relaxed) {
                device.read(start.elapsed().as_secs_f64())?;
                let accepted = device.counters().accepted;
                if accepted != replied {
                    replied = accepted;
                    device.write(&WRENCH)?;
                } else {
                    std::thread::yield_now();
                }
            }
            Ok(())
        },
        |addr| {
            let mut client = BridgeClient::connect(addr, None)?;
            let (mut times, mut lost, mut last_frame) = (Vec::with_capacity(n), 0, 0);
            for k in 0..n as u64 {
                let sent = Instant::now();
                client.send_pose(&pose(k))?;
                loop {
                    match client.recv_wrench(REPLY_TIMEOUT.saturating_sub(sent.elapsed()))? {
                        Some(r) if r.frame > last_frame => {
                            last_frame = r.frame;
                            times.push(sent.elapsed());
                        }
                        Some(_) => continue, // A late reply to an earlier, lost pose.
                        None => lost += 1,
                    }
                    break;
                }
            }
            Ok((times, lost))
        },
    )?;
    Ok(figure(&times, lost))
}

fn paced(n: usize) -> Result<BridgeFigure> {
    // Frames run on until the client stops them; room for the client's n ms plus start-up.
    let capacity = n + 10_000;
    let (accepted_at, (sent_at, replies)) = with_device(
        move |mut device, stop| {
            let start = Instant::now();
            // accepted_at[f - 1]: poses accepted when frame f's wrench was written.
            let mut accepted_at = Vec::with_capacity(capacity);
            let mut deadline = start;
            while !stop.load(Ordering::Relaxed) && accepted_at.len() < capacity {
                device.read(start.elapsed().as_secs_f64())?;
                device.write(&WRENCH)?;
                accepted_at.push(device.counters().accepted);
                deadline += FRAME;
                std::thread::sleep(deadline.saturating_duration_since(Instant::now()));
            }
            Ok(accepted_at)
        },
        |addr| {
            let mut client = BridgeClient::connect(addr, None)?;
            let mut sent_at = Vec::with_capacity(n);
            let mut replies = Vec::with_capacity(2 * n + 100);
            let start = Instant::now();
            // One frame plus 1/n of a frame: the phase sweeps one whole frame over the run.
            let period = FRAME + FRAME / n as u32;
            for k in 0..n as u64 {
                sent_at.push(Instant::now());
                client.send_pose(&pose(k))?;
                // Poll for replies until the next tick, so each is timed when it arrives (a
                // socket read timeout would end on the kernel's tick and lock the phases).
                let deadline = start + period * (k as u32 + 1);
                while Instant::now() < deadline {
                    match client.recv_wrench(Duration::ZERO)? {
                        Some(r) => replies.push((r.frame, Instant::now())),
                        None => std::thread::yield_now(),
                    }
                }
            }
            let end = Instant::now() + 10 * FRAME;
            while let Some(r) = client.recv_wrench(end.saturating_duration_since(Instant::now()))? {
                replies.push((r.frame, Instant::now()));
            }
            Ok((sent_at, replies))
        },
    )?;
    // Pose k (1-based sequence) is answered by the first reply whose frame had accepted ≥ k.
    let mut times = Vec::with_capacity(n);
    let mut next = 1usize;
    for (frame, received) in replies {
        let Some(&accepted) = usize::try_from(frame)
            .ok()
            .and_then(|f| f.checked_sub(1))
            .and_then(|i| accepted_at.get(i))
        else {
            bail!(
                "reply for frame {frame}, beyond the {} frames run",
                accepted_at.len()
            );
        };
        while next <= (accepted as usize).min(sent_at.len()) {
            times.push(received.saturating_duration_since(sent_at[next - 1]));
            next += 1;
        }
    }
    Ok(figure(&times, sent_at.len() + 1 - next))
}

/// Runs the benchmark with `round_trips` per measurement and prints JSON.
pub fn run(round_trips: u64, json: bool) -> Result<()> {
    let n = usize::try_from(round_trips)
        .ok()
        .filter(|n| (100..=1_000_000).contains(n))
        .context("--round-trips must be within [100, 1000000]")?;
    let raw = raw_udp_round_trips(n, POSE_IN_FLAGS_LEN, UdpPlacement::Unpinned)
        .context("raw UDP ping-pong")?;
    let raw_udp = figure(&raw, n.saturating_sub(raw.len()));
    let bridge_immediate = immediate(n).context("bridge round trips, immediate replies")?;
    let bridge_paced_1khz = paced(n).context("bridge round trips, 1 kHz frames")?;
    let ratio = |a: u64, b: u64| a as f64 / b.max(1) as f64;
    print_report(
        "bench bridge: device bridge round trip (pose out, wrench back) beside a raw UDP ping-pong",
        &BridgeReport {
            host_idle: crate::machine::HostIdle::read(),
            immediate_p50_over_raw_udp_p50: ratio(
                bridge_immediate.percentiles.p50_ns,
                raw_udp.percentiles.p50_ns,
            ),
            immediate_p999_over_raw_udp_p999: ratio(
                bridge_immediate.percentiles.p999_ns,
                raw_udp.percentiles.p999_ns,
            ),
            raw_udp,
            bridge_immediate,
            bridge_paced_1khz,
        },
        json,
    )
}
