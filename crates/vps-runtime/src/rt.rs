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
    let cores = allowed_cores().ok_or("cannot list the cores")?;
    let chosen = choose_core(core, &cores)?;
    if core_affinity::set_for_current(core_affinity::CoreId { id: chosen }) {
        Ok(chosen)
    } else {
        Err(format!("setting affinity to core {chosen} failed"))
    }
}

/// The one rule for the frame thread's core, shared by [`pin_current_thread`] and
/// [`frame_core`]: `requested` when it is among `allowed` (ascending), else an error; with no
/// request, the last allowed core (away from core 0, where most interrupts land).
fn choose_core(requested: Option<usize>, allowed: &[usize]) -> Result<usize, String> {
    match requested {
        Some(want) if allowed.contains(&want) => Ok(want),
        Some(want) => Err(format!("core {want} is not available to this process")),
        None => allowed
            .last()
            .copied()
            .ok_or_else(|| "no core available".to_string()),
    }
}

/// The core the frame thread is pinned to by [`request_realtime`]`(requested)`, as seen from the
/// calling thread: `requested` when the calling thread may use it, else (or when `None`) the last
/// core it may use. `None` when the cores cannot be listed or `requested` is not available.
pub fn frame_core(requested: Option<usize>) -> Option<usize> {
    choose_core(requested, &allowed_cores()?).ok()
}

/// The cores the calling thread may run on, ascending (`None`: the OS would not say).
pub fn allowed_cores() -> Option<Vec<usize>> {
    let mut ids: Vec<usize> = core_affinity::get_core_ids()?
        .into_iter()
        .map(|c| c.id)
        .collect();
    ids.sort_unstable();
    ids.dedup();
    Some(ids)
}

/// The cores of `allowed` other than `frame`: where every thread that is not the frame thread
/// should run. Empty when that would leave nothing or change nothing (one core, or `frame` not
/// among `allowed`): then nothing is pinned.
pub fn cores_away_from(frame: usize, allowed: &[usize]) -> Vec<usize> {
    if allowed.len() < 2 || !allowed.contains(&frame) {
        return Vec::new();
    }
    allowed.iter().copied().filter(|&c| c != frame).collect()
}

/// A CPU set holding `cores` (those past the set's capacity are left out), for
/// `sched_setaffinity`; built before a `fork` so that the child only makes the syscall.
#[cfg(target_os = "linux")]
pub fn cpu_set(cores: &[usize]) -> libc::cpu_set_t {
    // SAFETY: cpu_set_t is a plain bit array; all zeroes is the empty set.
    let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
    let capacity = 8 * std::mem::size_of::<libc::cpu_set_t>();
    for &c in cores.iter().filter(|&&c| c < capacity) {
        // SAFETY: `c` is below the set's capacity (checked above).
        unsafe { libc::CPU_SET(c, &mut set) };
    }
    set
}

/// Sets the affinity of thread or process `tid` (0: the calling thread) to the cores in `set`
/// ([`cpu_set`]). One syscall; it neither allocates nor locks (an error is the OS error code), so
/// a forked child may call it before `exec`.
#[cfg(target_os = "linux")]
pub fn apply_cpu_set(tid: libc::pid_t, set: &libc::cpu_set_t) -> std::io::Result<()> {
    // SAFETY: a valid, initialised cpu_set_t of the size passed.
    let rc = unsafe { libc::sched_setaffinity(tid, std::mem::size_of::<libc::cpu_set_t>(), set) };
    if rc == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// Sets the affinity of thread or process `tid` (0: the calling thread) to `cores`.
#[cfg(target_os = "linux")]
fn set_affinity(tid: libc::pid_t, cores: &[usize]) -> Result<(), String> {
    apply_cpu_set(tid, &cpu_set(cores)).map_err(|e| e.to_string())
}

#[cfg(not(target_os = "linux"))]
fn set_affinity(_tid: i32, _cores: &[usize]) -> Result<(), String> {
    Err("only implemented on Linux".to_string())
}

/// The cores thread or process `pid` may run on, ascending.
#[cfg(target_os = "linux")]
pub fn affinity_of(pid: u32) -> Result<Vec<usize>, String> {
    let pid = libc::pid_t::try_from(pid).map_err(|e| e.to_string())?;
    // SAFETY: all zeroes is the empty set; the size passed is the set's.
    let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
    let size = std::mem::size_of::<libc::cpu_set_t>();
    // SAFETY: a valid, writable cpu_set_t of the size passed.
    if unsafe { libc::sched_getaffinity(pid, size, &mut set) } != 0 {
        return Err(std::io::Error::last_os_error().to_string());
    }
    // SAFETY: `c` is below the set's capacity.
    Ok((0..8 * size)
        .filter(|&c| unsafe { libc::CPU_ISSET(c, &set) })
        .collect())
}

#[cfg(not(target_os = "linux"))]
pub fn affinity_of(_pid: u32) -> Result<Vec<usize>, String> {
    Err("only implemented on Linux".to_string())
}

/// Keeps a session's other threads and processes off the frame thread's core, and records what it
/// pinned for the run report ([`Placement`]). Cheap to clone (the record is shared).
#[derive(Clone, Debug)]
pub struct KeepOffFrameCore {
    frame: usize,
    away: Vec<usize>,
    record: std::sync::Arc<std::sync::Mutex<Vec<String>>>,
}

impl KeepOffFrameCore {
    /// For a frame thread that will be pinned to `requested` ([`frame_core`]), seen from the
    /// calling thread. `None` when there is nothing to keep off: one core, or the cores cannot be
    /// listed.
    pub fn for_frame(requested: Option<usize>) -> Option<KeepOffFrameCore> {
        let frame = frame_core(requested)?;
        let away = cores_away_from(frame, &allowed_cores()?);
        (!away.is_empty()).then(|| KeepOffFrameCore {
            frame,
            away,
            record: Default::default(),
        })
    }

    /// The frame thread's core.
    pub fn frame_core(&self) -> usize {
        self.frame
    }

    /// The cores everything else runs on.
    pub fn other_cores(&self) -> &[usize] {
        &self.away
    }

    /// Restricts the calling thread to [`Self::other_cores`] (threads it spawns afterwards
    /// inherit the mask) and records the outcome under `what` (e.g. the thread's role). Never
    /// fails.
    pub fn pin_this_thread(&self, what: &str) {
        let line = match set_affinity(0, &self.away) {
            Ok(()) => format!("{what}: cores {:?}", self.away),
            Err(e) => format!("{what}: refused ({e})"),
        };
        self.note(line);
    }

    /// Records a line for the report (e.g. a child process pinned at spawn).
    pub fn note(&self, line: String) {
        if let Ok(mut record) = self.record.lock() {
            record.push(line);
        }
    }

    /// What was pinned so far, identical lines merged with their count.
    pub fn placement(&self) -> Placement {
        let mut lines = self.record.lock().map(|r| r.clone()).unwrap_or_default();
        lines.sort();
        let mut pinned: Vec<String> = Vec::new();
        let mut i = 0;
        while i < lines.len() {
            let n = lines[i..].iter().take_while(|l| **l == lines[i]).count();
            pinned.push(if n == 1 {
                lines[i].clone()
            } else {
                format!("{} (x{n})", lines[i])
            });
            i += n;
        }
        Placement {
            frame_core: self.frame,
            other_cores: self.away.clone(),
            pinned,
        }
    }
}

/// Where a session's threads and processes were placed (the `placement` of the run report).
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Placement {
    /// The core the frame thread is pinned to (when the OS grants it: see the report's `rt`).
    pub frame_core: usize,
    /// The cores every other thread and process of the session was restricted to.
    pub other_cores: Vec<usize>,
    /// One line per thread role or process: what was pinned where, or why it was refused.
    pub pinned: Vec<String>,
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

    #[test]
    fn the_mask_leaves_out_the_frame_core_only_when_another_core_remains() {
        assert_eq!(cores_away_from(3, &[0, 1, 2, 3]), vec![0, 1, 2]);
        assert_eq!(cores_away_from(0, &[0, 5]), vec![5]);
        // One core: nothing changes.
        assert!(cores_away_from(0, &[0]).is_empty());
        // A frame core the process may not use: nothing changes.
        assert!(cores_away_from(7, &[0, 1]).is_empty());
        assert!(cores_away_from(0, &[]).is_empty());
    }

    #[test]
    fn the_frame_core_is_the_last_allowed_or_the_one_asked_for() {
        let allowed = allowed_cores().expect("cores listed");
        assert_eq!(frame_core(None), allowed.last().copied());
        assert_eq!(frame_core(Some(allowed[0])), Some(allowed[0]));
        assert_eq!(frame_core(Some(usize::MAX)), None);
    }

    #[test]
    fn a_thread_pinned_away_cannot_run_on_the_frame_core() {
        let allowed = allowed_cores().expect("cores listed");
        let frame = *allowed.last().unwrap();
        let (keep, after) = std::thread::spawn(move || {
            let keep = KeepOffFrameCore::for_frame(None);
            if let Some(keep) = &keep {
                keep.pin_this_thread("test thread");
            }
            (keep, allowed_cores().unwrap())
        })
        .join()
        .unwrap();
        match keep {
            None => {
                eprintln!("one core ({allowed:?}): nothing to keep off");
                assert_eq!(after, allowed);
            }
            Some(keep) => {
                assert_eq!(keep.frame_core(), frame);
                assert!(!after.contains(&frame), "{after:?}");
                assert_eq!(after, keep.other_cores());
                let placement = keep.placement();
                assert_eq!(placement.frame_core, frame);
                assert_eq!(
                    placement.pinned,
                    vec![format!("test thread: cores {:?}", keep.other_cores())]
                );
            }
        }
        // Read back by process id: this process (its main thread) is untouched.
        assert_eq!(affinity_of(std::process::id()).unwrap(), allowed);
        // The test thread itself is untouched.
        assert_eq!(allowed_cores().unwrap(), allowed);
    }

    #[test]
    fn identical_lines_are_merged_with_their_count() {
        let keep = KeepOffFrameCore {
            frame: 1,
            away: vec![0],
            record: Default::default(),
        };
        keep.note("b".into());
        keep.note("a".into());
        keep.note("b".into());
        assert_eq!(
            keep.placement().pinned,
            vec!["a".to_string(), "b (x2)".into()]
        );
    }
}
