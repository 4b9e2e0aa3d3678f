//! Shared by the bridge tests: polling a bridge device until datagrams have arrived.
#![allow(dead_code)]

use std::time::{Duration, Instant};

use vps_device::HapticDevice;
use vps_haptic::HandleSample;
use vps_input::{BridgeCounters, BridgeDevice};

/// Bounds every wait for loopback delivery; never reached when all is well.
pub const DEADLINE: Duration = Duration::from_secs(5);

/// Reads `dev` at device time `*t` until `done(counters)` holds, advancing `*t` by `step` (s)
/// after every read that does not finish, with a 0.2 ms pause between reads; returns the last
/// sample. Panics after [`DEADLINE`].
pub fn poll_until(
    dev: &mut BridgeDevice,
    t: &mut f64,
    step: f64,
    done: impl Fn(&BridgeCounters) -> bool,
) -> HandleSample {
    let start = Instant::now();
    loop {
        let s = dev.read(*t).expect("read");
        if done(&dev.counters()) {
            return s;
        }
        assert!(
            start.elapsed() < DEADLINE,
            "datagrams not delivered: {:?}",
            dev.counters()
        );
        *t += step;
        std::thread::sleep(Duration::from_micros(200));
    }
}
