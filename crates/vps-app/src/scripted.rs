//! The scripted simulated session of `vps demo`, the viewer benchmark and the sweep: the scene's
//! simulated hand on its script, paced at 1 kHz or back to back ([`run_scripted`]).

use anyhow::Result;
use vps_haptic::HapticParams;
use vps_runtime::{run_loop, LoopConfig, LoopReport, SignalStop, StateFeedSender};
use vps_session::{DeviceChoice, SessionAssets};

/// How [`run_scripted`] runs its session.
#[derive(Clone, Copy, Debug, Default)]
pub struct Scripted {
    /// At 1 kHz on the wall clock; otherwise frames back to back (the same physics).
    pub paced: bool,
    /// Keep the handle trace (for a study).
    pub record_trace: bool,
}

impl Scripted {
    /// Paced at 1 kHz (`true`) or back to back, no trace kept.
    pub fn paced(paced: bool) -> Scripted {
        Scripted {
            paced,
            record_trace: false,
        }
    }
}

/// Runs one session of the scene's simulated hand (its script) on `assets` with `params`, for
/// at most `seconds` (the script's length at most); `paced` runs at 1 kHz on the wall clock,
/// otherwise frames run back to back (the physics is identical: the device is given the scheduled
/// tick time either way). Every frame is published to `feed` when given (a viewer). When `signals`
/// are given, one of them ends the session early (the device written zero first).
pub fn run_scripted(
    assets: &SessionAssets,
    params: HapticParams,
    seconds: f64,
    threads: usize,
    how: Scripted,
    feed: Option<StateFeedSender>,
    signals: Option<&SignalStop>,
) -> Result<LoopReport> {
    let script = assets.script()?;
    let frames = ((seconds.min(script.duration()) / params.dt).round() as u64).max(1);
    let config = LoopConfig {
        frames: Some(frames),
        threads,
        realtime: how.paced,
        free_running: !how.paced,
        record_trace: how.record_trace,
        ..LoopConfig::default()
    };
    let mut plan = assets.plan(&DeviceChoice::Simulated, script, config)?;
    plan.setup.params = params;
    let report = run_loop(
        assets.tree.clone(),
        assets.classed_shell(),
        match signals {
            Some(signals) => plan.into_stopped_setup(feed, signals),
            None => plan.into_setup(feed),
        },
    )?;
    if let Some(err) = &report.device_error {
        anyhow::bail!("the device failed: {err}");
    }
    Ok(report)
}
