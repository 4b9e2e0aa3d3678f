//! Mutual TLS with operator-pinned certificates (docs/architecture.md#exact-sums-and-the-cluster: only pinned certificates may join).
//!
//! Every node has a self-signed certificate and key ([`make_cert`], PEM files). The operator lists
//! the certificates each side accepts (`--pin FILE`, repeatable). Both verifiers accept a peer only
//! when its end-entity certificate is byte-for-byte one of the pinned certificates, then check the
//! TLS 1.3 handshake signature against its key. Names, dates and chains play no part. The
//! coordinator is the QUIC server and requires a client certificate; a refused peer is logged
//! (`tracing::warn`, with the name it was made for and its SHA-256 fingerprint) and counted.
//!
//! One crypto provider, `ring`, is passed explicitly to every config (no process-wide default).

use crate::ClusterError;
use rustls::client::danger::{HandshakeSignatureValid, ServerCertVerified, ServerCertVerifier};
use rustls::crypto::CryptoProvider;
use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, PrivateKeyDer, ServerName, UnixTime};
use rustls::server::danger::{ClientCertVerified, ClientCertVerifier};
use rustls::{CertificateError, DigitallySignedStruct, DistinguishedName, SignatureScheme};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// The TLS server name workers use for the coordinator (ignored by the pinning verifier).
pub const SERVER_NAME: &str = "vps-coordinator";
/// The ALPN protocol of the cluster.
pub const ALPN: &[u8] = b"vps-cluster/1";

/// A node's certificate and private key.
#[derive(Debug)]
pub struct TlsIdentity {
    /// The certificate (DER).
    pub cert: CertificateDer<'static>,
    /// The private key (DER).
    pub key: PrivateKeyDer<'static>,
}

impl Clone for TlsIdentity {
    fn clone(&self) -> Self {
        TlsIdentity {
            cert: self.cert.clone(),
            key: self.key.clone_key(),
        }
    }
}

impl TlsIdentity {
    /// A fresh self-signed ECDSA P-256 certificate for `name` (in memory).
    pub fn generate(name: &str) -> Result<TlsIdentity, ClusterError> {
        let ck = rcgen::generate_simple_self_signed(vec![name.to_string()])
            .map_err(|e| ClusterError::Tls(format!("cannot generate a certificate: {e}")))?;
        let key = PrivateKeyDer::try_from(ck.key_pair.serialize_der())
            .map_err(|e| ClusterError::Tls(format!("generated key: {e}")))?;
        Ok(TlsIdentity {
            cert: ck.cert.der().clone(),
            key,
        })
    }

    /// Loads a PEM certificate and a PEM private key, and checks that the key is the
    /// certificate's (a key from another `vps cert` run is refused here, naming both files,
    /// rather than at every connection).
    pub fn load(cert: &Path, key: &Path) -> Result<TlsIdentity, ClusterError> {
        let identity = TlsIdentity {
            cert: load_cert(cert)?,
            key: read_pem(key, "a PEM private key")?,
        };
        if !identity.key_matches_cert() {
            return Err(ClusterError::File {
                path: key.to_path_buf(),
                message: format!(
                    "not the private key of the certificate {} (give the .key that `vps cert` wrote beside that .crt)",
                    cert.display()
                ),
            });
        }
        Ok(identity)
    }

    /// Whether the private key is the one whose public half the certificate carries (an
    /// unusable key, e.g. of an unsupported algorithm, counts as not matching).
    pub fn key_matches_cert(&self) -> bool {
        let Ok(signing_key) = provider()
            .key_provider
            .load_private_key(self.key.clone_key())
        else {
            return false;
        };
        rustls::sign::CertifiedKey::new(vec![self.cert.clone()], signing_key)
            .keys_match()
            .is_ok()
    }
}

/// Loads one PEM certificate (the first in the file).
pub fn load_cert(path: &Path) -> Result<CertificateDer<'static>, ClusterError> {
    read_pem(path, "a PEM certificate")
}

/// The largest PEM file read, in bytes (64 KiB; a `vps cert` certificate or key is under 1 KiB).
const MAX_PEM_FILE_BYTES: u64 = 64 * 1024;

/// Reads the first `what` of the PEM file `path`: a regular file of at most
/// [`MAX_PEM_FILE_BYTES`] (a pipe or device named by mistake is refused at once, see `vps-files`).
fn read_pem<T: PemObject>(path: &Path, what: &str) -> Result<T, ClusterError> {
    let bytes = vps_files::read_regular(path, MAX_PEM_FILE_BYTES)
        .map_err(|e| pem_error(path, what, rustls::pki_types::pem::Error::Io(e)))?;
    T::from_pem_slice(&bytes).map_err(|e| pem_error(path, what, e))
}

/// A PEM file that could not be used: one that cannot be read says so (missing, permission
/// denied), one that can but holds no `what` says that.
fn pem_error(path: &Path, what: &str, e: rustls::pki_types::pem::Error) -> ClusterError {
    let message = match e {
        rustls::pki_types::pem::Error::Io(io)
            if io.kind() == std::io::ErrorKind::PermissionDenied =>
        {
            format!(
                "cannot read {what} file: {io} (the user running vps, `vps` under the systemd units, must be able to read it: deploy/README.md section 2)"
            )
        }
        rustls::pki_types::pem::Error::Io(io) => format!("cannot read {what} file: {io}"),
        other => format!("not {what}: {other}"),
    };
    ClusterError::File {
        path: path.to_path_buf(),
        message,
    }
}

/// Loads the pinned certificates, one PEM file each. Errors on an empty list.
pub fn load_pins(paths: &[PathBuf]) -> Result<Vec<CertificateDer<'static>>, ClusterError> {
    if paths.is_empty() {
        return Err(ClusterError::Tls(
            "no pinned certificate given (--pin FILE)".into(),
        ));
    }
    paths.iter().map(|p| load_cert(p)).collect()
}

/// One side of the cluster's mutual TLS: this node's certificate and key, and the peer
/// certificates it admits (pinned byte for byte). The coordinator's pins are its workers'
/// certificates; a worker's, its coordinators'.
#[derive(Clone, Debug)]
pub struct PeerTls {
    /// This node's certificate and key.
    pub identity: TlsIdentity,
    /// The peer certificates admitted.
    pub pins: Vec<CertificateDer<'static>>,
}

impl PeerTls {
    /// An identity (`cert`, `key`) and the certificates it admits (`pins`), from PEM files
    /// ([`TlsIdentity::load`], [`load_pins`]).
    pub fn load(cert: &Path, key: &Path, pins: &[PathBuf]) -> Result<PeerTls, ClusterError> {
        Ok(PeerTls {
            identity: TlsIdentity::load(cert, key)?,
            pins: load_pins(pins)?,
        })
    }
}

/// The paths [`make_cert`] wrote.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CertFiles {
    /// `DIR/NAME.crt` (PEM certificate; give it to the other side's `--pin`).
    pub cert: PathBuf,
    /// `DIR/NAME.key` (PEM private key, mode 0600 on Unix).
    pub key: PathBuf,
}

/// `vps cert --out DIR --name NAME`: writes a fresh self-signed certificate and key to
/// `DIR/NAME.crt` and `DIR/NAME.key` (creating `DIR`). Refuses to overwrite existing files.
pub fn make_cert(dir: &Path, name: &str) -> Result<CertFiles, ClusterError> {
    let valid_name = !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_' || c == '.');
    if !valid_name {
        return Err(ClusterError::Tls(format!(
            "certificate name `{name}`: use letters, digits, '-', '_' or '.'"
        )));
    }
    let ck = rcgen::generate_simple_self_signed(vec![name.to_string()])
        .map_err(|e| ClusterError::Tls(format!("cannot generate a certificate: {e}")))?;
    let file_err = |path: &Path, e: std::io::Error| ClusterError::File {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    std::fs::create_dir_all(dir).map_err(|e| file_err(dir, e))?;
    let files = CertFiles {
        cert: dir.join(format!("{name}.crt")),
        key: dir.join(format!("{name}.key")),
    };
    for path in [&files.cert, &files.key] {
        if path.exists() {
            return Err(file_err(
                path,
                std::io::Error::new(std::io::ErrorKind::AlreadyExists, "exists already"),
            ));
        }
    }
    write_private(&files.key, ck.key_pair.serialize_pem().as_bytes())
        .map_err(|e| file_err(&files.key, e))?;
    std::fs::write(&files.cert, ck.cert.pem()).map_err(|e| file_err(&files.cert, e))?;
    Ok(files)
}

fn write_private(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write;
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    options.open(path)?.write_all(bytes)
}

/// The command that shows any certificate file's fingerprint exactly as [`fingerprint`] writes it
/// (`FILE` stands for the `.crt`); it prints `sha256 Fingerprint=` (older versions `SHA256
/// Fingerprint=`) before the digits. `sha256sum FILE` gives another digest: that of the PEM text.
pub const FINGERPRINT_COMMAND: &str = "openssl x509 -in FILE -noout -fingerprint -sha256";

/// A certificate's SHA-256 fingerprint, the one convention of vps (`vps cert`, `vps deploy init`,
/// the coordinator's log of a refused peer, the docs): the SHA-256 of its DER bytes, in upper-case
/// hex with a colon between bytes (`3F:A2:…`, 95 characters), as [`FINGERPRINT_COMMAND`] prints it.
pub fn fingerprint(cert: &[u8]) -> String {
    let digest = ring::digest::digest(&ring::digest::SHA256, cert);
    let hex: Vec<String> = digest.as_ref().iter().map(|b| format!("{b:02X}")).collect();
    hex.join(":")
}

/// The names a certificate was made for (its DNS subject alternative names: the `--name` of
/// `vps cert`), comma-separated; `?` when it has none or cannot be read.
pub fn certificate_names(cert: &CertificateDer<'_>) -> String {
    let names: Vec<String> = webpki::EndEntityCert::try_from(cert)
        .map(|c| c.valid_dns_names().map(str::to_string).collect())
        .unwrap_or_default();
    if names.is_empty() {
        "?".into()
    } else {
        names.join(",")
    }
}

/// Accepts exactly the pinned certificates, as client or server verifier.
#[derive(Debug)]
struct PinnedVerifier {
    pins: Vec<CertificateDer<'static>>,
    provider: Arc<CryptoProvider>,
    refused: Arc<AtomicU64>,
    role: &'static str,
}

impl PinnedVerifier {
    fn check(&self, end_entity: &CertificateDer<'_>) -> Result<(), rustls::Error> {
        if self.pins.iter().any(|p| p.as_ref() == end_entity.as_ref()) {
            return Ok(());
        }
        self.refused.fetch_add(1, Ordering::Relaxed);
        tracing::warn!(
            "refused a {} with an unpinned certificate: `{}` (sha256 {}); to admit it, pin its .crt here",
            self.role,
            certificate_names(end_entity),
            fingerprint(end_entity)
        );
        Err(rustls::Error::InvalidCertificate(
            CertificateError::ApplicationVerificationFailure,
        ))
    }
}

/// A signature check of the verifier traits, `$method`, delegated to rustls' `$check` with the
/// provider's algorithms (the same for both traits).
macro_rules! pinned_signature {
    ($method:ident, $check:path) => {
        fn $method(
            &self,
            message: &[u8],
            cert: &CertificateDer<'_>,
            dss: &DigitallySignedStruct,
        ) -> Result<HandshakeSignatureValid, rustls::Error> {
            $check(
                message,
                cert,
                dss,
                &self.provider.signature_verification_algorithms,
            )
        }
    };
}

/// The signature checks both verifier traits ask for ([`pinned_signature`]).
macro_rules! pinned_signatures {
    () => {
        pinned_signature!(
            verify_tls12_signature,
            rustls::crypto::verify_tls12_signature
        );
        pinned_signature!(
            verify_tls13_signature,
            rustls::crypto::verify_tls13_signature
        );
        fn supported_verify_schemes(&self) -> Vec<SignatureScheme> {
            self.provider
                .signature_verification_algorithms
                .supported_schemes()
        }
    };
}

impl ServerCertVerifier for PinnedVerifier {
    fn verify_server_cert(
        &self,
        end_entity: &CertificateDer<'_>,
        _intermediates: &[CertificateDer<'_>],
        _server_name: &ServerName<'_>,
        _ocsp_response: &[u8],
        _now: UnixTime,
    ) -> Result<ServerCertVerified, rustls::Error> {
        self.check(end_entity)
            .map(|()| ServerCertVerified::assertion())
    }
    pinned_signatures!();
}

impl ClientCertVerifier for PinnedVerifier {
    fn root_hint_subjects(&self) -> &[DistinguishedName] {
        &[]
    }
    fn verify_client_cert(
        &self,
        end_entity: &CertificateDer<'_>,
        _intermediates: &[CertificateDer<'_>],
        _now: UnixTime,
    ) -> Result<ClientCertVerified, rustls::Error> {
        self.check(end_entity)
            .map(|()| ClientCertVerified::assertion())
    }
    pinned_signatures!();
}

/// The crypto provider and a verifier admitting only `pins` (peers of `role`; refusals counted
/// in `refused`).
fn pinned(
    pins: Vec<CertificateDer<'static>>,
    refused: Arc<AtomicU64>,
    role: &'static str,
) -> (Arc<CryptoProvider>, Arc<PinnedVerifier>) {
    let provider = provider();
    let verifier = Arc::new(PinnedVerifier {
        pins,
        provider: provider.clone(),
        refused,
        role,
    });
    (provider, verifier)
}

fn provider() -> Arc<CryptoProvider> {
    Arc::new(rustls::crypto::ring::default_provider())
}

fn tls_err(e: impl std::fmt::Display) -> ClusterError {
    ClusterError::Tls(e.to_string())
}

/// QUIC transport settings shared by both sides: keep-alive 500 ms and a 3 s idle timeout, so a
/// killed peer is noticed within seconds (the frame path never waits for that: it falls back).
fn transport() -> Arc<quinn::TransportConfig> {
    let mut t = quinn::TransportConfig::default();
    t.keep_alive_interval(Some(Duration::from_millis(500)));
    // IdleTimeout from a VarInt is in milliseconds.
    t.max_idle_timeout(Some(quinn::VarInt::from_u32(3_000).into()));
    t.datagram_receive_buffer_size(Some(1 << 20));
    Arc::new(t)
}

/// The coordinator's QUIC server config: TLS 1.3, presents `tls.identity`, client certificate
/// required and one of `tls.pins`. `refused` counts peers refused for an unpinned certificate.
pub fn server_config(
    tls: &PeerTls,
    refused: Arc<AtomicU64>,
) -> Result<quinn::ServerConfig, ClusterError> {
    let (provider, verifier) = pinned(tls.pins.clone(), refused, "worker");
    let mut tls = rustls::ServerConfig::builder_with_provider(provider)
        .with_protocol_versions(&[&rustls::version::TLS13])
        .map_err(tls_err)?
        .with_client_cert_verifier(verifier)
        .with_single_cert(
            vec![tls.identity.cert.clone()],
            tls.identity.key.clone_key(),
        )
        .map_err(tls_err)?;
    tls.alpn_protocols = vec![ALPN.to_vec()];
    let quic = quinn::crypto::rustls::QuicServerConfig::try_from(tls).map_err(tls_err)?;
    let mut config = quinn::ServerConfig::with_crypto(Arc::new(quic));
    config.transport_config(transport());
    Ok(config)
}

/// A worker's QUIC client config: TLS 1.3, presents `tls.identity`, accepts only a server
/// certificate among `tls.pins`. `refused` counts coordinators refused for an unpinned certificate.
pub fn client_config(
    tls: &PeerTls,
    refused: Arc<AtomicU64>,
) -> Result<quinn::ClientConfig, ClusterError> {
    let (provider, verifier) = pinned(tls.pins.clone(), refused, "coordinator");
    let mut tls = rustls::ClientConfig::builder_with_provider(provider)
        .with_protocol_versions(&[&rustls::version::TLS13])
        .map_err(tls_err)?
        .dangerous()
        .with_custom_certificate_verifier(verifier)
        .with_client_auth_cert(
            vec![tls.identity.cert.clone()],
            tls.identity.key.clone_key(),
        )
        .map_err(tls_err)?;
    tls.alpn_protocols = vec![ALPN.to_vec()];
    let quic = quinn::crypto::rustls::QuicClientConfig::try_from(tls).map_err(tls_err)?;
    let mut config = quinn::ClientConfig::new(Arc::new(quic));
    config.transport_config(transport());
    Ok(config)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn message(err: ClusterError) -> String {
        err.to_string()
    }

    #[test]
    fn a_key_of_another_certificate_is_refused_naming_both_files() {
        let dir = tempfile::tempdir().unwrap();
        let a = make_cert(dir.path(), "a").unwrap();
        let b = make_cert(dir.path(), "b").unwrap();
        assert!(TlsIdentity::load(&a.cert, &a.key).is_ok());
        let m = message(TlsIdentity::load(&a.cert, &b.key).unwrap_err());
        assert!(m.starts_with(&format!("{}: ", b.key.display())), "{m}");
        assert!(
            m.contains(&format!(
                "not the private key of the certificate {}",
                a.cert.display()
            )),
            "{m}"
        );
        let pins = std::slice::from_ref(&b.cert);
        assert!(PeerTls::load(&a.cert, &b.key, pins).is_err());
    }

    #[test]
    fn a_missing_file_is_not_called_a_bad_pem_file() {
        let dir = tempfile::tempdir().unwrap();
        let a = make_cert(dir.path(), "a").unwrap();
        let missing = dir.path().join("missing.crt");
        let m = message(TlsIdentity::load(&missing, &a.key).unwrap_err());
        assert!(
            m.starts_with(&format!(
                "{}: cannot read a PEM certificate file: ",
                missing.display()
            )),
            "{m}"
        );
        assert!(!m.contains("not a PEM"), "{m}");
        let m = message(TlsIdentity::load(&a.cert, &dir.path().join("missing.key")).unwrap_err());
        assert!(m.contains("cannot read a PEM private key file: "), "{m}");
    }

    #[test]
    fn a_file_without_pem_says_so() {
        let dir = tempfile::tempdir().unwrap();
        let a = make_cert(dir.path(), "a").unwrap();
        let text = dir.path().join("notes.crt");
        std::fs::write(&text, "hello\n").unwrap();
        let m = message(load_cert(&text).unwrap_err());
        assert!(
            m.starts_with(&format!("{}: not a PEM certificate: ", text.display())),
            "{m}"
        );
        // A certificate given as the key: no private key in it.
        let m = message(TlsIdentity::load(&a.cert, &a.cert).unwrap_err());
        assert!(m.contains("not a PEM private key"), "{m}");
    }

    #[test]
    fn a_certificate_is_named_and_fingerprinted_as_openssl_prints_it() {
        let dir = tempfile::tempdir().unwrap();
        let a = make_cert(dir.path(), "worker-h3").unwrap();
        let cert = load_cert(&a.cert).unwrap();
        assert_eq!(certificate_names(&cert), "worker-h3");
        let hex = fingerprint(&cert);
        assert_eq!(hex.len(), 95);
        // SHA-256 of the empty input, to pin the digest itself and openssl's format.
        assert_eq!(
            fingerprint(b""),
            "E3:B0:C4:42:98:FC:1C:14:9A:FB:F4:C8:99:6F:B9:24:27:AE:41:E4:64:9B:93:4C:A4:95:99:1B:78:52:B8:55"
        );
        assert_eq!(
            certificate_names(&CertificateDer::from(vec![1u8, 2, 3])),
            "?"
        );
    }
}
