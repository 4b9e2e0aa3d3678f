//! `vps`: command-line entry point. Work in progress.
fn main() {
    println!("vps: work in progress");
}
