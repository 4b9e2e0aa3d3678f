//! Bounds on what a command line asks: thread and process counts by the machine's cores, session
//! lengths by a finite maximum, the bridge's mapping and timeouts by the bridge's own ranges,
//! memory sizes, frame strides and coordinates. Used as clap value parsers, so an error names the
//! flag and the value (clap adds them) and says the allowed range.

use vps_input::bridge::config::POSE_TIMEOUT_RANGE_S;
use vps_input::bridge::mapping::{MAX_FORCE_SCALE, SCALE_RANGE};

/// Compute threads or worker processes per core at most: more only queue behind each other
/// (`--threads 10000` started 10,003 threads and missed 4,031 of 1,000 deadlines).
pub const PER_CORE: usize = 4;

/// The longest session (s): 1e7 s, about 116 days; a longer one is a typo or an overflow. One
/// bound for the command line and the sweep file.
pub use vps_session::sweep_file::MAX_SESSION_SECONDS;

/// This machine's cores as the OS reports them (1 when it cannot tell).
fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// The most workers a coordinator waits for: the shell is split into
/// [`vps_cluster::protocol::MAX_CLASSES`] (64) classes and a worker's share is at least one, so a
/// 65th worker could get no work (`workers = 1000000` was accepted and the coordinator waited for
/// them).
pub const MAX_WORKERS: usize = vps_cluster::protocol::MAX_CLASSES as usize;

/// A coordinator's worker count (`--workers`, `workers` in its config file) in
/// `1..=`[`MAX_WORKERS`].
pub fn parse_workers(text: &str) -> Result<usize, String> {
    let n: usize = text
        .trim()
        .parse()
        .map_err(|_| format!("not a whole number; allowed 1..={MAX_WORKERS}"))?;
    if (1..=MAX_WORKERS).contains(&n) {
        Ok(n)
    } else {
        Err(format!(
            "allowed 1..={MAX_WORKERS} (the shell is split into {MAX_WORKERS} classes, at least \
             one per worker)"
        ))
    }
}

/// A thread or process count in `1..=PER_CORE × cores`.
pub fn parse_count(text: &str) -> Result<usize, String> {
    let limit = PER_CORE * cores();
    let n: usize = text
        .parse()
        .map_err(|_| format!("not a whole number; allowed 1..={limit}"))?;
    if (1..=limit).contains(&n) {
        Ok(n)
    } else {
        Err(format!(
            "allowed 1..={limit} ({PER_CORE} × the {} cores of this machine)",
            cores()
        ))
    }
}

/// Checks a total of threads over several flags (`what` names them) against the same bound.
pub fn check_thread_total(what: &str, total: usize) -> anyhow::Result<()> {
    let limit = PER_CORE * cores();
    if total > limit {
        anyhow::bail!(
            "{what} = {total} threads: allowed at most {limit} ({PER_CORE} × the {} cores of this \
             machine)",
            cores()
        );
    }
    Ok(())
}

/// A session length in seconds, finite and in `(0, MAX_SESSION_SECONDS]`.
pub fn parse_seconds(text: &str) -> Result<f64, String> {
    let range = format!("allowed: finite, > 0 and ≤ {MAX_SESSION_SECONDS:e} s");
    let s: f64 = text.parse().map_err(|_| format!("not a number; {range}"))?;
    if s.is_finite() && s > 0.0 && s <= MAX_SESSION_SECONDS {
        Ok(s)
    } else {
        Err(range)
    }
}

/// Shortest `--join-wait` (s).
pub const MIN_JOIN_WAIT_SECONDS: f64 = 0.1;

/// Longest `--join-wait` (s): an hour.
pub const MAX_JOIN_WAIT_SECONDS: f64 = 3600.0;

/// `--join-wait`: seconds a coordinator waits for its workers, [`MIN_JOIN_WAIT_SECONDS`]..=
/// [`MAX_JOIN_WAIT_SECONDS`].
pub fn parse_join_wait(text: &str) -> Result<f64, String> {
    let range = format!("allowed {MIN_JOIN_WAIT_SECONDS}..={MAX_JOIN_WAIT_SECONDS} s");
    let s: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("not a number; {range}"))?;
    if (MIN_JOIN_WAIT_SECONDS..=MAX_JOIN_WAIT_SECONDS).contains(&s) {
        Ok(s)
    } else {
        Err(range)
    }
}

/// A socket address, IP:port (`192.168.1.10:7800`, `[fe80::1]:7800`). A host name is refused
/// saying so: the cluster services never resolve names.
pub fn parse_ip_port(text: &str) -> Result<std::net::SocketAddr, String> {
    text.trim().parse().map_err(|_| {
        let looks_like_a_name = text
            .rsplit_once(':')
            .is_some_and(|(host, port)| port.parse::<u16>().is_ok() && host.parse::<std::net::IpAddr>().is_err());
        if looks_like_a_name {
            format!("`{text}` names a host: give its IP address and port (e.g. 192.168.1.10:7800); host names are not resolved")
        } else {
            format!("`{text}` is not IP:port (e.g. 192.168.1.10:7800 or [fe80::1]:7800)")
        }
    })
}

/// `--study-every`, `--every`: a whole number of frames in 1..=1000000.
pub fn parse_frame_stride(text: &str) -> Result<usize, String> {
    match text.trim().parse::<usize>() {
        Ok(n) if (1..=1_000_000).contains(&n) => Ok(n),
        _ => Err("a whole number of frames; allowed 1..=1000000".into()),
    }
}

/// `--device`: one of the forms `vps_session::DeviceChoice::parse` accepts, checked before any
/// work (the device itself is opened once the scene is built).
pub fn parse_device(text: &str) -> Result<String, String> {
    vps_session::DeviceChoice::parse(text).map(|_| text.to_string())
}

/// A finite number of `text` that `ok` accepts, else an error giving the allowed `range`.
pub fn parse_in_range(text: &str, ok: impl Fn(f64) -> bool, range: &str) -> Result<f64, String> {
    text.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite() && ok(*v))
        .ok_or_else(|| format!("`{text}`: allowed {range}"))
}

/// `--map-scale`: scene metres per device metre, in the bridge's [`SCALE_RANGE`].
pub fn parse_map_scale(text: &str) -> Result<f64, String> {
    let range = format!("{} to {}", SCALE_RANGE.start(), SCALE_RANGE.end());
    parse_in_range(text, |v| SCALE_RANGE.contains(&v), &range)
}

/// `--force-scale`: device force per scene force, in (0, [`MAX_FORCE_SCALE`]].
pub fn parse_force_scale(text: &str) -> Result<f64, String> {
    let range = format!("above 0, up to {MAX_FORCE_SCALE}");
    parse_in_range(text, |v| v > 0.0 && v <= MAX_FORCE_SCALE, &range)
}

/// `--pose-timeout-ms`: the bridge's [`POSE_TIMEOUT_RANGE_S`], in ms.
pub fn parse_pose_timeout_ms(text: &str) -> Result<f64, String> {
    let (low, high) = (POSE_TIMEOUT_RANGE_S.start(), POSE_TIMEOUT_RANGE_S.end());
    let range = format!("{} to {} (ms)", low * 1e3, high * 1e3);
    parse_in_range(text, |v| POSE_TIMEOUT_RANGE_S.contains(&(v / 1e3)), &range)
}

/// Parses `X,Y,Z` (three finite numbers).
pub fn parse_triple(text: &str) -> Result<[f64; 3], String> {
    let parts: Vec<&str> = text.split(',').collect();
    let [x, y, z] = parts[..] else {
        return Err(format!("`{text}`: expected three numbers X,Y,Z"));
    };
    let mut out = [0.0; 3];
    for (o, p) in out.iter_mut().zip([x, y, z]) {
        *o = p
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("`{p}` in `{text}` is not a finite number"))?;
    }
    Ok(out)
}

/// Parses a memory size in bytes: a bare integer (bytes) or a number followed by `KiB`, `MiB`,
/// `GiB`, `TiB` (powers of 1024) or `kB`, `MB`, `GB`, `TB` (powers of 1000), case-insensitive.
/// The result is at least one byte, or an error saying what was wrong.
pub fn parse_bytes(text: &str) -> Result<u64, String> {
    let lower = text.to_ascii_lowercase();
    let units: [(&str, f64); 9] = [
        ("kib", 1024.0),
        ("mib", 1024.0 * 1024.0),
        ("gib", 1024.0 * 1024.0 * 1024.0),
        ("tib", 1024.0 * 1024.0 * 1024.0 * 1024.0),
        ("kb", 1e3),
        ("mb", 1e6),
        ("gb", 1e9),
        ("tb", 1e12),
        ("b", 1.0),
    ];
    let bytes = vps_units::scaled_number(&lower, &units)
        .ok_or_else(|| format!("'{text}' is not a memory size (examples: 16GiB, 512MiB, 8GB)"))?;
    if !bytes.is_finite() || bytes < 1.0 || bytes >= u64::MAX as f64 {
        return Err(format!(
            "'{text}' must be a memory size from 1 byte to 16 EiB"
        ));
    }
    Ok(bytes as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_are_bounded_by_the_machine() {
        let limit = PER_CORE * cores();
        assert_eq!(parse_count("1"), Ok(1));
        assert_eq!(parse_count(&limit.to_string()), Ok(limit));
        let err = parse_count(&(limit + 1).to_string()).unwrap_err();
        assert!(err.contains(&format!("1..={limit}")), "{err}");
        assert!(parse_count("0").is_err());
        assert!(parse_count("-3").is_err());
    }

    #[test]
    fn seconds_must_be_finite_and_positive() {
        assert_eq!(parse_seconds("2.5"), Ok(2.5));
        for bad in ["0", "-1", "nan", "inf", "1e300", "x"] {
            let err = parse_seconds(bad).unwrap_err();
            assert!(err.contains("> 0") && err.contains("1e7 s"), "{bad}: {err}");
        }
    }
}

#[cfg(test)]
mod memory_size_tests {
    use super::parse_bytes;

    #[test]
    fn memory_sizes() {
        assert_eq!(parse_bytes("16GiB").unwrap(), 16 << 30);
        assert_eq!(parse_bytes("512 MiB").unwrap(), 512 << 20);
        assert_eq!(parse_bytes("8GB").unwrap(), 8_000_000_000);
        assert_eq!(parse_bytes("1.5gib").unwrap(), 3 << 29);
        assert_eq!(parse_bytes("4096").unwrap(), 4096);
        for bad in ["", "GiB", "-1GiB", "0", "nan", "1e30TiB", "12 parsecs"] {
            assert!(parse_bytes(bad).is_err(), "{bad} accepted");
        }
    }
}
