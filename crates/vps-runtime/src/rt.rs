//! Best-effort real-time scheduling for the frame thread: SCHED_FIFO and core pinning. Never fails:
//! what was refused is reported in [`RtGrant`].

/// What the OS granted the calling thread.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct RtGrant {
    /// SCHED_FIFO was granted.
    pub fifo: bool,
    /// The SCHED_FIFO priority granted, when `fifo`.
    pub priority: Option<i32>,
    /// The core the thread was pinned to, if pinning succeeded.
    pub pinned_core: Option<usize>,
    /// Why a request was refused (empty when everything asked for was granted).
    pub errors: Vec<String>,
}

/// The SCHED_FIFO priority requested: high, but below the kernel's own threads (99).
pub const FIFO_PRIORITY: i32 = 80;

/// Requests SCHED_FIFO at [`FIFO_PRIORITY`] (capped to the system maximum) for the calling thread
/// and pins it to `core` (or, when `None`, to the last core the process may use, away from core 0
/// where most interrupts land). Call from the frame thread itself. Never fails, never panics.
pub fn request_realtime(core: Option<usize>) -> RtGrant {
    let mut grant = RtGrant::default();
    match set_fifo() {
        Ok(priority) => {
            grant.fifo = true;
            grant.priority = Some(priority);
        }
        Err(e) => grant.errors.push(format!("SCHED_FIFO refused: {e}")),
    }
    match pin_current_thread(core) {
        Ok(id) => grant.pinned_core = Some(id),
        Err(e) => grant.errors.push(format!("core pinning refused: {e}")),
    }
    grant
}

#[cfg(target_os = "linux")]
fn set_fifo() -> Result<i32, String> {
    // SAFETY: plain syscalls on the calling thread (pid 0) with a valid, initialised sched_param.
    unsafe {
        let max = libc::sched_get_priority_max(libc::SCHED_FIFO);
        if max < 0 {
            return Err(std::io::Error::last_os_error().to_string());
        }
        let priority = FIFO_PRIORITY.min(max);
        let param = libc::sched_param {
            sched_priority: priority,
        };
        if libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) != 0 {
            return Err(std::io::Error::last_os_error().to_string());
        }
        Ok(priority)
    }
}

#[cfg(not(target_os = "linux"))]
fn set_fifo() -> Result<i32, String> {
    Err("only implemented on Linux".to_string())
}

/// Pins the calling thread to `core` (or, when `None`, to the last core the process may use);
/// returns the core's id, or why the OS refused.
pub fn pin_current_thread(core: Option<usize>) -> Result<usize, String> {
    let cores = core_affinity::get_core_ids().ok_or("cannot list the cores")?;
    let chosen = match core {
        Some(want) => cores
            .iter()
            .find(|c| c.id == want)
            .copied()
            .ok_or_else(|| format!("core {want} is not available to this process"))?,
        None => *cores.last().ok_or("no core available")?,
    };
    if core_affinity::set_for_current(chosen) {
        Ok(chosen.id)
    } else {
        Err(format!("setting affinity to core {} failed", chosen.id))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_refusal_is_reported_not_fatal() {
        // Run on a throwaway thread so the test harness thread keeps its scheduling.
        let grant = std::thread::spawn(|| request_realtime(Some(usize::MAX)))
            .join()
            .unwrap();
        assert_eq!(grant.pinned_core, None);
        assert!(
            grant.errors.iter().any(|e| e.contains("not available")),
            "{:?}",
            grant.errors
        );
        assert_eq!(grant.fifo, grant.priority.is_some());
        if !grant.fifo {
            assert!(grant.errors.iter().any(|e| e.contains("SCHED_FIFO")));
        }
    }
}
