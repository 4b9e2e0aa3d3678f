//! The `kind` of a scene file's `[device]` section (and of `--device`): which device a session
//! is driven by, as written. Opening it is `vps-session`'s (`DeviceChoice`); this is the syntax.

use std::net::SocketAddr;
use std::path::PathBuf;

/// The default address of the UDP device bridge.
pub const DEFAULT_BRIDGE_ADDR: &str = "127.0.0.1:7700";

/// A device as a scene file or the command line names it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DeviceKind {
    /// `sim`: the simulated hand on the scene's script.
    Simulated,
    /// `spacemouse`: the first SpaceMouse-family HID device found (input only).
    SpaceMouse,
    /// `bridge[:ADDR]`: the UDP device bridge bound to the address (default
    /// [`DEFAULT_BRIDGE_ADDR`]).
    Bridge(SocketAddr),
    /// `replay:FILE`: a recorded handle trace, as written (relative paths are the caller's to
    /// resolve).
    Replay(PathBuf),
}

impl DeviceKind {
    /// Parses `sim`, `spacemouse`, `bridge`, `bridge:ADDR` or `replay:FILE`; the error says which
    /// forms are allowed.
    pub fn parse(text: &str) -> Result<DeviceKind, String> {
        Ok(match text.split_once(':') {
            None if text == "sim" => DeviceKind::Simulated,
            None if text == "spacemouse" => DeviceKind::SpaceMouse,
            None if text == "bridge" => {
                DeviceKind::Bridge(DEFAULT_BRIDGE_ADDR.parse().expect("a valid address"))
            }
            Some(("bridge", addr)) => DeviceKind::Bridge(addr.parse().map_err(|_| {
                format!("bridge:{addr}: not an address like {DEFAULT_BRIDGE_ADDR}")
            })?),
            Some(("replay", path)) if !path.is_empty() => DeviceKind::Replay(PathBuf::from(path)),
            _ => {
                return Err(format!(
                    "'{text}': expected sim, spacemouse, bridge[:ADDR] or replay:FILE"
                ))
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_form_parses_and_others_are_refused_naming_the_forms() {
        assert_eq!(DeviceKind::parse("sim"), Ok(DeviceKind::Simulated));
        assert_eq!(DeviceKind::parse("spacemouse"), Ok(DeviceKind::SpaceMouse));
        assert_eq!(
            DeviceKind::parse("bridge"),
            Ok(DeviceKind::Bridge(DEFAULT_BRIDGE_ADDR.parse().unwrap()))
        );
        assert_eq!(
            DeviceKind::parse("bridge:0.0.0.0:9000"),
            Ok(DeviceKind::Bridge("0.0.0.0:9000".parse().unwrap()))
        );
        assert_eq!(
            DeviceKind::parse("replay:a/b.trace"),
            Ok(DeviceKind::Replay(PathBuf::from("a/b.trace")))
        );
        for bad in ["", "replay:", "bridge:nowhere", "haption", "sim:1"] {
            let e = DeviceKind::parse(bad).unwrap_err();
            assert!(e.contains("bridge") || e.contains("address"), "{bad}: {e}");
        }
    }
}
