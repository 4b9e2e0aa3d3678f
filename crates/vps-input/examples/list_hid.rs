//! Lists every HID device hidapi sees and marks the drivable SpaceMice.
//! Run: `cargo run -p vps-input --example list_hid`.

fn main() {
    match vps_input::list_devices() {
        Ok(devices) if devices.is_empty() => println!("no HID devices found"),
        Ok(devices) => {
            for d in devices {
                println!("{d}");
            }
        }
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
    }
}
