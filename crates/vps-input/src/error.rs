//! Errors of the SpaceMouse enumeration and opening (the bridge has its own
//! [`BridgeError`](crate::bridge::BridgeError)).

use crate::spacemouse::ConfigError;

/// Why HID devices could not be listed or a SpaceMouse could not be opened.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InputError {
    /// The hidapi context could not be created.
    #[error("cannot initialise hidapi: {message}")]
    HidInit {
        /// hidapi's message.
        message: String,
    },
    /// A HID device could not be opened (permissions: see the crate docs on udev rules).
    #[error("cannot open HID device {path}: {message}")]
    Open {
        /// The device path.
        path: String,
        /// hidapi's message.
        message: String,
    },
    /// No known SpaceMouse was found.
    #[error("no known SpaceMouse among {found} HID devices (see `vps devices`)")]
    NoDevice {
        /// How many HID devices were listed.
        found: usize,
    },
    /// The rate-control configuration is invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
}
