//! This machine's state recorded beside every timing benchmark: its load ([`load_average`]) and
//! how its idle CPUs wait ([`HostIdle`]): recorded beside every timing benchmark: on a VM, waking a
//! thread on another vCPU that has halted waits for the hypervisor to run that vCPU again (about
//! 70 µs on the project's Firecracker VM), and guest halt polling (`cpuidle-haltpoll`'s
//! `guest_halt_poll_ns`) is what avoids it. Read from sysfs; a file that does not exist is `None`.

use serde::Serialize;
use std::path::Path;

const CPUIDLE: &str = "/sys/devices/system/cpu/cpuidle";
const HALTPOLL: &str = "/sys/module/haltpoll/parameters/guest_halt_poll_ns";

/// The idle settings in force when a benchmark ran.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct HostIdle {
    /// The cpuidle driver (`haltpoll` in a KVM guest, `intel_idle` on bare metal, ...).
    pub cpuidle_driver: Option<String>,
    /// The cpuidle governor.
    pub cpuidle_governor: Option<String>,
    /// How long (ns) an idle vCPU polls before it halts, where the `haltpoll` driver is loaded;
    /// 0 halts at once.
    pub guest_halt_poll_ns: Option<u64>,
}

impl HostIdle {
    /// The settings of this machine now.
    pub fn read() -> HostIdle {
        HostIdle::read_from(Path::new(CPUIDLE), Path::new(HALTPOLL))
    }

    fn read_from(cpuidle: &Path, haltpoll: &Path) -> HostIdle {
        let text = |p: &Path| {
            std::fs::read_to_string(p)
                .ok()
                .map(|s| s.trim().to_string())
                .filter(|s| !s.is_empty())
        };
        HostIdle {
            cpuidle_driver: text(&cpuidle.join("current_driver")),
            cpuidle_governor: text(&cpuidle.join("current_governor")),
            guest_halt_poll_ns: text(haltpoll).and_then(|s| s.parse().ok()),
        }
    }
}

/// The 1-minute load average from `/proc/loadavg` (None where there is none).
pub fn load_average() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/loadavg").ok()?;
    text.split_whitespace().next()?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_what_exists_and_leaves_the_rest_none() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("current_driver"), "haltpoll\n").unwrap();
        let poll = dir.path().join("guest_halt_poll_ns");
        std::fs::write(&poll, "200000\n").unwrap();
        let idle = HostIdle::read_from(dir.path(), &poll);
        assert_eq!(
            idle,
            HostIdle {
                cpuidle_driver: Some("haltpoll".into()),
                cpuidle_governor: None,
                guest_halt_poll_ns: Some(200_000),
            }
        );
        std::fs::write(&poll, "not a number").unwrap();
        assert_eq!(
            HostIdle::read_from(dir.path(), &poll).guest_halt_poll_ns,
            None
        );
    }
}
