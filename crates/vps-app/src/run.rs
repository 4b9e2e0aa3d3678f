//! Running a prepared session on a backend ([`Prepared::run`]): the loop on this process's own
//! threads ([`Backend::Local`]) or split with workers ([`Backend::Cluster`]), then its end
//! ([`crate::finish()`]).

use crate::cluster::ClusterBackend;
use crate::finish::finish;
use crate::prepare::{LiveSession, Prepared};
use anyhow::Result;
use vps_runtime::run_loop;

/// Where a session's frames are computed.
pub enum Backend {
    /// This process: the frame thread and the request's `threads − 1` helpers.
    Local,
    /// A coordinator here and workers elsewhere ([`Prepared::run_coordinated`]); boxed, as it
    /// carries the coordinator's TLS identity and gather settings.
    Cluster(Box<ClusterBackend>),
}

impl Prepared {
    /// Runs the session on `backend` to its end: makes it live (viewer, signal handlers), runs the
    /// 1 kHz loop, then, once the device has been written zero, writes its recording, report and
    /// study and prints its figures ([`finish`]). Fails with a [`crate::exit::SessionExit`] (its
    /// exit status) when the session did not run to its end.
    pub fn run(self, backend: Backend) -> Result<()> {
        match backend {
            Backend::Local => {
                let LiveSession {
                    assets,
                    viewer: _viewer,
                    setup,
                    bridge,
                    signals,
                    request,
                    outputs,
                } = self.go_live()?;
                let report = run_loop(assets.tree.clone(), assets.classed_shell(), setup)?;
                finish(
                    &request,
                    outputs,
                    &signals,
                    &assets,
                    &report,
                    bridge.as_ref(),
                    None::<&()>,
                )
            }
            Backend::Cluster(cluster) => self.run_coordinated(*cluster)?.finish(),
        }
    }
}
