//! TLS for the one port: a certificate chain and key from PEM files, ALPN
//! offering HTTP/2 (gRPC) and HTTP/1.1 (browsers, curl), through rustls.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use tokio_rustls::TlsAcceptor;
use tokio_rustls::rustls::pki_types::pem::PemObject;
use tokio_rustls::rustls::pki_types::{CertificateDer, PrivateKeyDer};
use tokio_rustls::rustls::{self, ServerConfig};

/// A certificate or key that cannot be used.
#[derive(Debug, thiserror::Error)]
#[error("cannot use the TLS {what}: {message}: {}", path.display())]
pub struct TlsError {
    what: &'static str,
    message: String,
    path: PathBuf,
}

/// The acceptor for `cert` (a PEM chain, the server's certificate first)
/// and `key` (a PEM private key: PKCS#8, PKCS#1 or SEC1).
pub fn acceptor(cert: &Path, key: &Path) -> Result<TlsAcceptor, TlsError> {
    let chain: Vec<CertificateDer<'static>> = CertificateDer::pem_file_iter(cert)
        .map_err(|e| TlsError { what: "certificate", message: e.to_string(), path: cert.to_path_buf() })?
        .collect::<Result<_, _>>()
        .map_err(|e| TlsError { what: "certificate", message: e.to_string(), path: cert.to_path_buf() })?;
    if chain.is_empty() {
        return Err(TlsError {
            what: "certificate",
            message: "no CERTIFICATE block in the file".into(),
            path: cert.to_path_buf(),
        });
    }
    let private = PrivateKeyDer::from_pem_file(key).map_err(|e| TlsError {
        what: "key",
        message: e.to_string(),
        path: key.to_path_buf(),
    })?;
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let mut config = ServerConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .map_err(|e| TlsError { what: "certificate", message: e.to_string(), path: cert.to_path_buf() })?
        .with_no_client_auth()
        .with_single_cert(chain, private)
        .map_err(|e| TlsError {
            what: "key",
            message: format!("it does not fit the certificate {}: {e}", cert.display()),
            path: key.to_path_buf(),
        })?;
    config.alpn_protocols = vec![b"h2".to_vec(), b"http/1.1".to_vec()];
    Ok(TlsAcceptor::from(Arc::new(config)))
}
