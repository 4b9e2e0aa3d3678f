//! A device wrapper that logs every wrench written to it and fails, panics or raises a flag on
//! chosen reads.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use vps_device::{DeviceError, DeviceLimits, HapticDevice};
use vps_haptic::{HandleSample, Wrench};

/// Every wrench written to a [`LoggingDevice`], in order.
pub type Writes = Arc<Mutex<Vec<Wrench>>>;

/// Called after write number `n` (1-based) was logged, on the frame thread, before the next
/// frame starts (so blocking in it delays the session but never a frame's deadline).
pub type WriteHook = Box<dyn FnMut(u64) + Send>;

/// Wraps a device: logs every write into [`Writes`]; optionally fails or panics at a given read,
/// fails the write that follows a given read, raises a flag at a given read and runs a hook after
/// every write. Reads are numbered from 0 for `fail_read_at`, `fail_write_at` and
/// `panic_read_at`.
pub struct LoggingDevice {
    inner: Box<dyn HapticDevice>,
    writes: Writes,
    reads: u64,
    /// Read number (0-based) that returns a hardware error instead of a sample.
    pub fail_read_at: Option<u64>,
    /// The write after read number (0-based) that returns a hardware error (it is still logged).
    pub fail_write_at: Option<u64>,
    /// Read number (0-based) that panics, like a bug in a driver.
    pub panic_read_at: Option<u64>,
    trip: Option<(u64, Arc<AtomicBool>)>,
    hook: Option<WriteHook>,
}

impl LoggingDevice {
    /// Wraps `inner`, failing nothing; returns the device and its write log.
    pub fn new(inner: Box<dyn HapticDevice>) -> (LoggingDevice, Writes) {
        let writes = Writes::default();
        let device = LoggingDevice {
            inner,
            writes: writes.clone(),
            reads: 0,
            fail_read_at: None,
            fail_write_at: None,
            panic_read_at: None,
            trip: None,
            hook: None,
        };
        (device, writes)
    }

    /// Raises `flag` at read number `read` (1-based; never when 0).
    pub fn trip_at(mut self, read: u64, flag: Arc<AtomicBool>) -> LoggingDevice {
        self.trip = Some((read, flag));
        self
    }

    /// Runs `hook` after every write.
    pub fn with_hook(mut self, hook: WriteHook) -> LoggingDevice {
        self.hook = Some(hook);
        self
    }
}

impl HapticDevice for LoggingDevice {
    fn read(&mut self, t: f64) -> Result<HandleSample, DeviceError> {
        self.reads += 1;
        if let Some((at, flag)) = &self.trip {
            if self.reads == *at {
                flag.store(true, Ordering::Relaxed);
            }
        }
        if self.panic_read_at == Some(self.reads - 1) {
            panic!("logging device: a bug in the driver");
        }
        if self.fail_read_at == Some(self.reads - 1) {
            return Err(DeviceError::Hardware {
                device: "logging device".into(),
                message: "unplugged".into(),
            });
        }
        self.inner.read(t)
    }

    fn write(&mut self, w: &Wrench) -> Result<(), DeviceError> {
        let n = {
            let mut writes = self.writes.lock().unwrap();
            writes.push(*w);
            writes.len() as u64
        };
        if self.fail_write_at == Some(self.reads.wrapping_sub(1)) {
            return Err(DeviceError::Hardware {
                device: "logging device".into(),
                message: "bus error".into(),
            });
        }
        if let Some(hook) = &mut self.hook {
            hook(n);
        }
        self.inner.write(w)
    }

    fn limits(&self) -> DeviceLimits {
        self.inner.limits()
    }

    fn name(&self) -> &str {
        self.inner.name()
    }
}

/// Asserts that two write traces are the same, frame by frame, to the bit.
pub fn assert_same_writes(got: &[Wrench], want: &[Wrench]) {
    assert_eq!(got.len(), want.len(), "device write count");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        let bits =
            |w: &Wrench| [w.force.to_array(), w.torque.to_array()].map(|v| v.map(f64::to_bits));
        assert_eq!(bits(g), bits(w), "frame {i}: {g:?} != {w:?}");
    }
}
