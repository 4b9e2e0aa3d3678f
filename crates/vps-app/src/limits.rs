//! Bounds on the resources a command line names: thread and process counts by the machine's
//! cores, session lengths by a finite maximum. Used as clap value parsers, so an error names the
//! flag and the value (clap adds them) and says the allowed range.

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
