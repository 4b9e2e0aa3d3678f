//! 3Dconnexion SpaceMouse-family devices as rate-controlled 6-DOF handles.
//!
//! Module map: [`report`] (pure HID report parser), [`devices`] (known ids, HID enumeration),
//! [`rate_control`] (pure deflection → velocity → pose), [`driver`] (the thin hidapi-backed
//! [`SpaceMouse`] implementing `HapticDevice`).

pub mod devices;
pub mod driver;
pub mod rate_control;
pub mod report;

pub use devices::{list_devices, lookup, HidDeviceInfo, KnownDevice, KNOWN_DEVICES};
pub use driver::{ReportCounters, ReportSource, SpaceMouse};
pub use rate_control::{ConfigError, RateControl, SpaceMouseConfig, BUTTON_LEFT, BUTTON_RIGHT};
pub use report::{parse_report, Layout, Report, ReportError};
