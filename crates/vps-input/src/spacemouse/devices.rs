//! Known SpaceMouse-family devices and HID enumeration.
//!
//! The table holds the best-known vendor/product ids and report layouts collected from public
//! sources (spacenavd, the Linux kernel's hid-ids, vendor documentation); it is not an official
//! list and has not been checked against every device here (no hardware was attached when it was
//! written). An unknown 3Dconnexion product can still be opened by path with
//! [`Layout::Auto`].

use super::report::Layout;
use crate::InputError;

/// 3Dconnexion devices of the Logitech era use Logitech's vendor id.
pub const VENDOR_LOGITECH: u16 = 0x046d;
/// 3Dconnexion's own vendor id (newer devices).
pub const VENDOR_3DCONNEXION: u16 = 0x256f;

/// One known SpaceMouse-family product.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KnownDevice {
    /// USB vendor id.
    pub vendor_id: u16,
    /// USB product id.
    pub product_id: u16,
    /// Marketing name.
    pub name: &'static str,
    /// The report layout the device is believed to send.
    pub layout: Layout,
}

/// A product sold under Logitech's vendor id ([`VENDOR_LOGITECH`]).
const fn logitech(product_id: u16, name: &'static str, layout: Layout) -> KnownDevice {
    KnownDevice {
        vendor_id: VENDOR_LOGITECH,
        product_id,
        name,
        layout,
    }
}

/// A product sold under 3Dconnexion's own vendor id ([`VENDOR_3DCONNEXION`]).
const fn three_dconnexion(product_id: u16, name: &'static str, layout: Layout) -> KnownDevice {
    KnownDevice {
        vendor_id: VENDOR_3DCONNEXION,
        product_id,
        name,
        layout,
    }
}

/// Best-known SpaceMouse-family ids (see the module docs for how reliable they are).
pub const KNOWN_DEVICES: &[KnownDevice] = &[
    logitech(0xc603, "SpaceMouse Plus XT", Layout::Split),
    logitech(0xc605, "CADMan", Layout::Split),
    logitech(0xc606, "SpaceMouse Classic", Layout::Split),
    logitech(0xc621, "SpaceBall 5000", Layout::Split),
    logitech(0xc623, "SpaceTraveller", Layout::Split),
    logitech(0xc625, "SpacePilot", Layout::Split),
    logitech(0xc626, "SpaceNavigator", Layout::Split),
    logitech(0xc627, "SpaceExplorer", Layout::Split),
    logitech(0xc628, "SpaceNavigator for Notebooks", Layout::Split),
    logitech(0xc629, "SpacePilot Pro", Layout::Split),
    logitech(0xc62b, "SpaceMouse Pro", Layout::Split),
    three_dconnexion(0xc62e, "SpaceMouse Wireless (cabled)", Layout::Combined),
    three_dconnexion(0xc62f, "SpaceMouse Wireless (receiver)", Layout::Combined),
    three_dconnexion(0xc631, "SpaceMouse Pro Wireless (cabled)", Layout::Combined),
    three_dconnexion(
        0xc632,
        "SpaceMouse Pro Wireless (receiver)",
        Layout::Combined,
    ),
    three_dconnexion(0xc635, "SpaceMouse Compact", Layout::Auto),
    three_dconnexion(0xc652, "3Dconnexion Universal Receiver", Layout::Combined),
];

/// The table entry for `(vendor_id, product_id)`, if any.
pub fn lookup(vendor_id: u16, product_id: u16) -> Option<&'static KnownDevice> {
    KNOWN_DEVICES
        .iter()
        .find(|d| d.vendor_id == vendor_id && d.product_id == product_id)
}

/// One HID device found by [`list_devices`] (any HID device, not only SpaceMice).
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct HidDeviceInfo {
    /// USB vendor id.
    pub vendor_id: u16,
    /// USB product id.
    pub product_id: u16,
    /// Product string reported by the device, or the table name, or "" when neither is known.
    pub name: String,
    /// Manufacturer string reported by the device ("" when absent).
    pub manufacturer: String,
    /// Platform path to open the device with (e.g. `/dev/hidraw3` on Linux).
    pub path: String,
    /// HID usage page of this interface (0 when the backend does not report it).
    pub usage_page: u16,
    /// HID usage of this interface (8 = multi-axis controller on usage page 1).
    pub usage: u16,
    /// USB interface number (-1 when unknown).
    pub interface_number: i32,
    /// True when the device is in [`KNOWN_DEVICES`], so [`crate::SpaceMouse`] can drive it.
    pub drivable: bool,
    /// Layout from the table (`None` for unknown devices).
    pub layout: Option<Layout>,
}

impl std::fmt::Display for HidDeviceInfo {
    /// One line: `vvvv:pppp  name  path  usage page:usage  drivable (layout)` or `-`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let name = if self.name.is_empty() {
            "(unnamed)"
        } else {
            &self.name
        };
        write!(
            f,
            "{:04x}:{:04x}  {name}  {}  usage {:#06x}:{:#06x}  ",
            self.vendor_id, self.product_id, self.path, self.usage_page, self.usage
        )?;
        match self.layout {
            Some(layout) if self.drivable => write!(f, "drivable ({layout:?} reports)"),
            _ => write!(f, "-"),
        }
    }
}

/// Lists every HID device visible to hidapi, in enumeration order. Allocates; blocks for the
/// enumeration (a few milliseconds); never called on the frame path.
///
/// With the `linux-native-basic-udev` backend, enumeration scans `/sys/class/hidraw`; a machine
/// without HID devices (a container, CI) yields `Ok(vec![])`, as does a missing or unreadable sysfs
/// (the backend maps those to an empty list). `Err(InputError::HidInit)` is returned only when
/// the hidapi context itself fails to initialise (possible on other backends). On the container
/// this crate was written in (no `/dev/hidraw*`, empty `/sys/class/hidraw`) it returns
/// `Ok(vec![])`.
pub fn list_devices() -> Result<Vec<HidDeviceInfo>, InputError> {
    let api = hidapi::HidApi::new().map_err(|e| InputError::HidInit {
        message: e.to_string(),
    })?;
    Ok(api.device_list().map(describe).collect())
}

/// Converts hidapi's description into ours.
pub(crate) fn describe(info: &hidapi::DeviceInfo) -> HidDeviceInfo {
    let entry = lookup(info.vendor_id(), info.product_id());
    let name = match (info.product_string(), entry) {
        (Some(s), _) if !s.is_empty() => s.to_string(),
        (_, Some(k)) => k.name.to_string(),
        _ => String::new(),
    };
    HidDeviceInfo {
        vendor_id: info.vendor_id(),
        product_id: info.product_id(),
        name,
        manufacturer: info.manufacturer_string().unwrap_or("").to_string(),
        path: info.path().to_string_lossy().into_owned(),
        usage_page: info.usage_page(),
        usage: info.usage(),
        interface_number: info.interface_number(),
        drivable: entry.is_some(),
        layout: entry.map(|k| k.layout),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    #[test]
    fn table_has_unique_ids_and_the_named_models() {
        let mut seen = HashSet::new();
        for d in KNOWN_DEVICES {
            assert!(
                seen.insert((d.vendor_id, d.product_id)),
                "duplicate {:04x}:{:04x}",
                d.vendor_id,
                d.product_id
            );
            assert!(!d.name.is_empty());
        }
        assert_eq!(lookup(0x046d, 0xc626).unwrap().name, "SpaceNavigator");
        assert_eq!(lookup(0x046d, 0xc626).unwrap().layout, Layout::Split);
        assert_eq!(lookup(0x256f, 0xc62e).unwrap().layout, Layout::Combined);
        assert_eq!(
            lookup(0x256f, 0xc652).unwrap().name,
            "3Dconnexion Universal Receiver"
        );
        assert!(lookup(0x046d, 0xc52b).is_none(), "a Logitech receiver");
    }

    #[test]
    fn display_is_one_informative_line() {
        let d = HidDeviceInfo {
            vendor_id: 0x046d,
            product_id: 0xc626,
            name: "SpaceNavigator".into(),
            manufacturer: "3Dconnexion".into(),
            path: "/dev/hidraw3".into(),
            usage_page: 1,
            usage: 8,
            interface_number: 0,
            drivable: true,
            layout: Some(Layout::Split),
        };
        let line = d.to_string();
        assert_eq!(
            line,
            "046d:c626  SpaceNavigator  /dev/hidraw3  usage 0x0001:0x0008  drivable (Split reports)"
        );
        assert!(!line.contains('\n'));
    }

    #[test]
    fn list_devices_does_not_panic_and_marks_drivable_from_the_table() {
        // On this machine (no /dev/hidraw*) the list is empty; on a desktop it lists everything.
        let devices = list_devices().expect("linux-native enumeration does not fail to init");
        for d in &devices {
            assert_eq!(d.drivable, lookup(d.vendor_id, d.product_id).is_some());
            assert!(!d.path.is_empty());
        }
    }
}
