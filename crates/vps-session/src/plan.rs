//! The one way a session's [`SessionSetup`] for the runtime is made: a [`SessionPlan`] (parameters,
//! opened device, initial state, loop settings) plus where the loop publishes and what stops it.
//! [`stop_on_signals`] is the one place a session command installs its SIGINT, SIGTERM and SIGHUP
//! handlers.

use crate::device::{DeviceChoice, OpenedDevice};
use crate::parts::body_radius;
use crate::scene::SessionAssets;
use anyhow::Context;
use anyhow::Result;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use vps_device::script::Script;
use vps_haptic::HapticParams;
use vps_input::BridgeMonitor;
use vps_runtime::{
    ClassPool, LoopConfig, MovingPart, PartBody, PartsSetup, SessionSetup, SignalStop,
    StateFeedSender,
};

/// A session ready to run: the runtime's setup, still without the viewer feed and with a stop
/// flag nobody else holds (the `into_*setup` methods give it those), and the bridge's monitor.
pub struct SessionPlan {
    /// Validated haptic parameters, the opened device, the part's state at frame 0 and the frame
    /// loop settings; `feed` is `None` and `stop` a fresh, lowered flag until
    /// [`SessionPlan::into_setup_with_stop`] (or its shorthands) sets them.
    pub setup: SessionSetup,
    /// The bridge's counters and wrench log when the device is the UDP bridge: readable after the
    /// device has moved into the loop (clone it before [`SessionPlan::into_setup`]).
    pub bridge: Option<BridgeMonitor>,
}

impl SessionPlan {
    /// A plan driving the opened `device` with `params` and `config`.
    pub fn new(params: HapticParams, device: OpenedDevice, config: LoopConfig) -> SessionPlan {
        SessionPlan {
            setup: SessionSetup {
                params,
                device: device.device,
                initial: device.initial,
                config,
                feed: None,
                stop: Arc::new(AtomicBool::new(false)),
                parts: None,
            },
            bridge: device.bridge,
        }
    }

    /// The runtime's setup: publishing to `feed` when given, ended early when `stop` is raised.
    pub fn into_setup_with_stop(
        self,
        feed: Option<StateFeedSender>,
        stop: Arc<AtomicBool>,
    ) -> SessionSetup {
        SessionSetup {
            feed,
            stop,
            ..self.setup
        }
    }

    /// [`SessionPlan::into_setup_with_stop`] with a stop flag nobody raises: the session ends by
    /// its frame count or its device.
    pub fn into_setup(self, feed: Option<StateFeedSender>) -> SessionSetup {
        SessionSetup { feed, ..self.setup }
    }

    /// The runtime's setup, stopped by SIGINT, SIGTERM and SIGHUP: installs the handlers (the
    /// device is open from now on) and returns them with the setup, so that the report can say
    /// which signal ended the session. The loop then writes the exact zero wrench first.
    /// Allocates; setup-time only.
    pub fn into_live_setup(
        self,
        feed: Option<StateFeedSender>,
    ) -> Result<(SessionSetup, SignalStop)> {
        let signals = stop_on_signals()?;
        Ok((self.into_stopped_setup(feed, &signals), signals))
    }

    /// The runtime's setup, stopped by the handlers `signals` (installed once for several
    /// sessions of one command).
    pub fn into_stopped_setup(
        self,
        feed: Option<StateFeedSender>,
        signals: &SignalStop,
    ) -> SessionSetup {
        self.into_setup_with_stop(feed, signals.flag().clone())
    }
}

/// Installs SIGINT, SIGTERM and SIGHUP handlers that set a fresh stop flag (and record the
/// signal). They stay installed for the rest of the process: call this once the process holds a
/// device, in a command that ends after its session(s). Allocates; setup-time only.
pub fn stop_on_signals() -> Result<SignalStop> {
    let stop = Arc::new(AtomicBool::new(false));
    Ok(SignalStop::install(&stop)?)
}

impl SessionAssets {
    /// Opens `device` (the simulated hand follows `script`; the others start at its first pose;
    /// the bridge is set up by [`SessionAssets::bridge`]) and plans a session with the scene's
    /// parameters and `config`; a scene of several parts opens every other part's device too
    /// ([`SessionAssets::parts_setup`]). Blocking (opens the devices).
    pub fn plan(
        &self,
        device: &DeviceChoice,
        script: Script,
        config: LoopConfig,
    ) -> Result<SessionPlan> {
        let opened = device.open(script, &self.bridge)?;
        let parts = self.parts_setup(&config)?;
        let mut plan = SessionPlan::new(self.params, opened, config);
        plan.setup.parts = parts;
        Ok(plan)
    }
}

impl SessionAssets {
    /// The longest simulated hand's path (s): `first`'s (the first part's script) or, in a scene
    /// of several parts, another part's simulated hand's. Finds corridor detours (reads the voxmap).
    pub fn hands_duration(&self, first: &vps_device::script::Script) -> Result<f64> {
        let mut longest = first.duration();
        for p in &self.more_parts {
            if p.device == DeviceChoice::Simulated {
                longest = longest.max(p.hand.script(&self.tree)?.duration());
            }
        }
        Ok(longest)
    }

    /// The runtime's setup for the parts after the first: each part's device opened (a
    /// simulated hand on its own path), a local class pool of `config.threads` threads on the
    /// static voxmap for its shell, and every part's body. `None` in a one-part scene. Blocking
    /// (opens devices), allocates.
    pub fn parts_setup(&self, config: &LoopConfig) -> Result<Option<PartsSetup>> {
        let (Some(first_body), false) = (&self.part_body, self.more_parts.is_empty()) else {
            return Ok(None);
        };
        let mut others = Vec::with_capacity(self.more_parts.len());
        for p in &self.more_parts {
            let script = p.hand.script(&self.tree)?;
            let opened = p
                .device
                .open(script, &p.bridge)
                .with_context(|| format!("opening the device of part '{}'", p.name))?;
            let shell = p.shell.classed();
            let pool = ClassPool::new(self.tree.clone(), shell.clone(), config.threads)?;
            others.push(MovingPart {
                name: p.name.clone(),
                params: p.params,
                device: opened.device,
                initial: opened.initial,
                sampler: Box::new(pool),
                body: PartBody {
                    map: p.body.clone(),
                    shell,
                    radius: p.radius,
                },
            });
        }
        Ok(Some(PartsSetup {
            first: PartBody {
                map: first_body.clone(),
                shell: self.classed_shell(),
                radius: body_radius(&self.part_mesh, self.shell.points()),
            },
            others,
            margin: self.pair_margin,
        }))
    }
}
