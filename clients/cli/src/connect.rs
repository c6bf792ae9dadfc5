//! The connection to reliefd: plaintext or TLS by the address's scheme, the
//! bearer token on every call, and a refused call told in plain words.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use tonic::metadata::{Ascii, MetadataValue};
use tonic::service::Interceptor;
use tonic::transport::{Certificate, Channel, ClientTlsConfig};

/// The variable naming the CA certificate when `--ca` is not given.
pub const CA_ENV: &str = "RELIEF_CA";

/// Where the system keeps its CA certificates as one PEM bundle (Debian
/// and Ubuntu, Fedora and RHEL, Alpine, openSUSE), after `SSL_CERT_FILE`.
const SYSTEM_CA_BUNDLES: &[&str] = &[
    "/etc/ssl/certs/ca-certificates.crt",
    "/etc/pki/tls/certs/ca-bundle.crt",
    "/etc/ssl/cert.pem",
    "/etc/ssl/ca-bundle.pem",
];

/// What the user asked for: the address and, for TLS, the CA to trust.
pub struct Options<'a> {
    /// reliefd's address, `http://HOST:PORT` or `https://HOST:PORT`.
    pub server: &'a str,
    /// `--ca`, which only an `https://` address takes.
    pub ca: Option<&'a Path>,
    /// `RELIEF_CA`, read for an `https://` address when `--ca` is not given.
    pub ca_env: Option<PathBuf>,
}

impl Options<'_> {
    /// Whether the address asks for TLS (`https://`).
    pub fn is_tls(&self) -> bool {
        self.server.get(..8).is_some_and(|s| s.eq_ignore_ascii_case("https://"))
    }

    /// Whether the address is this machine's (`localhost`, 127.0.0.0/8,
    /// `::1`): nobody else is on the path to it.
    pub fn is_loopback(&self) -> bool {
        let Ok(uri) = self.server.parse::<tonic::transport::Uri>() else { return false };
        let host = uri.host().unwrap_or_default().trim_start_matches('[').trim_end_matches(']');
        host.eq_ignore_ascii_case("localhost") || host.parse::<std::net::IpAddr>().is_ok_and(|ip| ip.is_loopback())
    }

    /// Refuses to send a token in the clear to another machine: over
    /// plain `http://` anyone on the path reads it (and may then do what
    /// it lets them), unless `insecure` says to anyway.
    pub fn check_token_path(&self, token: bool, insecure: bool) -> anyhow::Result<()> {
        if token && !self.is_tls() && !self.is_loopback() && !insecure {
            bail!(
                "refusing to send the token over plain http:// to {}: anyone on the path could read it and use it; \
                 serve reliefd with TLS (--tls-cert, --tls-key) and use https://, or give --insecure to send it anyway",
                self.server
            );
        }
        Ok(())
    }
}

/// How calls went out, for what a failure says: with a token, over TLS.
#[derive(Debug, Clone, Copy)]
pub struct Sent {
    pub token: bool,
    pub tls: bool,
}

/// Adds `authorization: Bearer TOKEN` to every request (nothing without a
/// token).
#[derive(Clone)]
pub struct Bearer(Option<MetadataValue<Ascii>>);

impl Bearer {
    /// The token as sent: white space round it dropped (a token read from
    /// a file keeps its newline); one that cannot go in a header refused.
    pub fn new(token: Option<&str>) -> anyhow::Result<Self> {
        let Some(token) = token.map(str::trim).filter(|t| !t.is_empty()) else {
            return Ok(Self(None));
        };
        if !token.bytes().all(|b| b.is_ascii_graphic()) {
            bail!("the token holds white space or characters that cannot be sent in a header");
        }
        let value =
            format!("Bearer {token}").parse().context("the token holds characters that cannot be sent in a header")?;
        Ok(Self(Some(value)))
    }

    /// Whether a token is sent.
    pub fn is_set(&self) -> bool {
        self.0.is_some()
    }
}

impl Interceptor for Bearer {
    fn call(&mut self, mut request: tonic::Request<()>) -> Result<tonic::Request<()>, tonic::Status> {
        if let Some(value) = &self.0 {
            request.metadata_mut().insert("authorization", value.clone());
        }
        Ok(request)
    }
}

/// The channel to reliefd, connected (over TLS for `https://`).
pub async fn channel(options: &Options<'_>) -> anyhow::Result<Channel> {
    let server = options.server;
    let tls = options.is_tls();
    let mut endpoint = Channel::from_shared(server.to_owned())
        .with_context(|| format!("invalid server address '{server}'"))?
        // Wide HTTP/2 windows: a height tile (264 kB) arrives in one flight.
        .initial_stream_window_size(8 * 1024 * 1024)
        .initial_connection_window_size(16 * 1024 * 1024);
    if tls {
        let ca = ca_certificate(options.ca.map(Path::to_path_buf).or_else(|| options.ca_env.clone()))?;
        endpoint = endpoint
            .tls_config(ClientTlsConfig::new().ca_certificate(ca))
            .with_context(|| format!("cannot set up TLS for {server}"))?;
    } else if let Some(ca) = options.ca {
        bail!("--ca {} is for an https:// server; '{server}' is plaintext (use https://)", ca.display());
    }
    endpoint.connect().await.map_err(|e| {
        let why = chain(&e);
        let lower = why.to_ascii_lowercase();
        if tls && ["certificate", "tls", "handshake", "alert"].iter().any(|w| lower.contains(w)) {
            let hint = if options.ca.is_some() || options.ca_env.is_some() {
                "is its certificate for this host name, and signed by the CA in --ca or RELIEF_CA?"
            } else {
                "only the system's CAs are trusted: give the CA that signed reliefd's certificate with --ca PEM"
            };
            anyhow::anyhow!("cannot reach reliefd at {server} over TLS: {why} ({hint})")
        } else {
            anyhow::anyhow!("cannot reach reliefd at {server}: {why}")
        }
    })
}

/// An error and its sources, each once ("a: b: c"; a level whose words its
/// parent already ends with is left out).
fn chain(error: &dyn std::error::Error) -> String {
    let mut text = error.to_string();
    let mut source = error.source();
    while let Some(e) = source {
        let words = e.to_string();
        if !text.ends_with(&words) {
            text.push_str(": ");
            text.push_str(&words);
        }
        source = e.source();
    }
    text
}

/// The CA certificates to trust: the file given, else the system's bundle.
fn ca_certificate(given: Option<PathBuf>) -> anyhow::Result<Certificate> {
    let path = match given {
        Some(path) => path,
        None => system_bundle().context(
            "an https:// server needs the CA that signed its certificate: give --ca PEM or set RELIEF_CA \
             (no system CA bundle was found; SSL_CERT_FILE may name one)",
        )?,
    };
    let pem =
        std::fs::read(&path).map_err(|e| anyhow::anyhow!("cannot read the CA certificate: {e}: {}", path.display()))?;
    if !pem.windows(27).any(|w| w == b"-----BEGIN CERTIFICATE-----") {
        bail!(
            "cannot use the CA certificate: it holds no PEM certificate (-----BEGIN CERTIFICATE-----): {}",
            path.display()
        );
    }
    Ok(Certificate::from_pem(pem))
}

fn system_bundle() -> Option<PathBuf> {
    if let Some(file) = std::env::var_os("SSL_CERT_FILE").map(PathBuf::from).filter(|p| p.is_file()) {
        return Some(file);
    }
    SYSTEM_CA_BUNDLES.iter().map(PathBuf::from).find(|p| p.is_file())
}

/// A status's code as gRPC names it (`NOT_FOUND`).
fn code_name(code: tonic::Code) -> &'static str {
    use tonic::Code;
    match code {
        Code::Ok => "OK",
        Code::Cancelled => "CANCELLED",
        Code::Unknown => "UNKNOWN",
        Code::InvalidArgument => "INVALID_ARGUMENT",
        Code::DeadlineExceeded => "DEADLINE_EXCEEDED",
        Code::NotFound => "NOT_FOUND",
        Code::AlreadyExists => "ALREADY_EXISTS",
        Code::PermissionDenied => "PERMISSION_DENIED",
        Code::ResourceExhausted => "RESOURCE_EXHAUSTED",
        Code::FailedPrecondition => "FAILED_PRECONDITION",
        Code::Aborted => "ABORTED",
        Code::OutOfRange => "OUT_OF_RANGE",
        Code::Unimplemented => "UNIMPLEMENTED",
        Code::Internal => "INTERNAL",
        Code::Unavailable => "UNAVAILABLE",
        Code::DataLoss => "DATA_LOSS",
        Code::Unauthenticated => "UNAUTHENTICATED",
    }
}

/// A failed call in plain words: the daemon's message and the code's
/// name; a refusal says what to do about it, and a connection that broke
/// (a status made here, with the transport's error as its source) says why.
pub fn status_error(status: &tonic::Status, sent: Sent) -> anyhow::Error {
    if let Some(transport) = std::error::Error::source(status) {
        let hint = if sent.tls { "" } else { " (if reliefd serves TLS, its address is https://HOST:PORT)" };
        return anyhow::anyhow!("the connection to reliefd failed: {}{hint}", chain(transport));
    }
    let (message, code) = (status.message(), code_name(status.code()));
    match status.code() {
        tonic::Code::Unauthenticated => {
            let hint =
                if sent.token { "check --token or RELIEF_TOKEN" } else { "pass --token TOKEN or set RELIEF_TOKEN" };
            anyhow::anyhow!("reliefd refused the call: {message} ({code}); {hint}")
        }
        tonic::Code::PermissionDenied => anyhow::anyhow!("reliefd refused the call: {message} ({code})"),
        _ => anyhow::anyhow!("{message} ({code})"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_token_goes_in_the_clear_only_to_this_machine_or_when_told() {
        let at = |server| Options { server, ca: None, ca_env: None };
        for server in ["http://127.0.0.1:50051", "http://localhost:1", "http://[::1]:2", "http://127.8.0.1:3"] {
            assert!(at(server).check_token_path(true, false).is_ok(), "{server}");
        }
        let refused = at("http://10.0.0.5:50051").check_token_path(true, false).err().map(|e| e.to_string());
        assert!(refused.is_some_and(|e| e.contains("refusing to send the token over plain http://")));
        assert!(at("http://10.0.0.5:50051").check_token_path(true, true).is_ok(), "--insecure");
        assert!(at("https://relief.example:443").check_token_path(true, false).is_ok(), "TLS");
        assert!(at("http://10.0.0.5:50051").check_token_path(false, false).is_ok(), "no token");
    }

    #[test]
    fn a_token_goes_as_a_bearer_header_trimmed_and_none_without() -> anyhow::Result<()> {
        let mut bearer = Bearer::new(Some("  read-0123456789abcdef\n"))?;
        assert!(bearer.is_set());
        let request = bearer.call(tonic::Request::new(()))?;
        assert_eq!(
            request.metadata().get("authorization").map(MetadataValue::to_str).transpose()?,
            Some("Bearer read-0123456789abcdef")
        );
        for nothing in [None, Some(""), Some(" \n")] {
            let mut bearer = Bearer::new(nothing)?;
            assert!(!bearer.is_set());
            assert!(bearer.call(tonic::Request::new(()))?.metadata().get("authorization").is_none());
        }
        let refused = Bearer::new(Some("two words")).err().map(|e| e.to_string()).unwrap_or_default();
        assert!(refused.contains("white space"), "{refused}");
        Ok(())
    }

    #[test]
    fn refusals_are_plain_words_with_what_to_do() {
        let missing = tonic::Status::unauthenticated("missing token: send 'authorization: Bearer TOKEN'");
        assert_eq!(
            status_error(&missing, Sent { token: false, tls: false }).to_string(),
            "reliefd refused the call: missing token: send 'authorization: Bearer TOKEN' (UNAUTHENTICATED); \
             pass --token TOKEN or set RELIEF_TOKEN"
        );
        let wrong = tonic::Status::unauthenticated("the token is not one this reliefd accepts");
        assert_eq!(
            status_error(&wrong, Sent { token: true, tls: true }).to_string(),
            "reliefd refused the call: the token is not one this reliefd accepts (UNAUTHENTICATED); \
             check --token or RELIEF_TOKEN"
        );
        let denied = tonic::Status::permission_denied("this token may only read");
        assert_eq!(
            status_error(&denied, Sent { token: true, tls: false }).to_string(),
            "reliefd refused the call: this token may only read (PERMISSION_DENIED)"
        );
        let other = tonic::Status::not_found("no source has id 'nope'");
        assert_eq!(
            status_error(&other, Sent { token: false, tls: false }).to_string(),
            "no source has id 'nope' (NOT_FOUND)"
        );
    }

    #[test]
    fn a_ca_file_without_a_certificate_is_named() -> anyhow::Result<()> {
        let dir = std::env::temp_dir().join(format!("relief-cli-ca-{}", std::process::id()));
        std::fs::create_dir_all(&dir)?;
        let path = dir.join("not-a-ca.pem");
        std::fs::write(&path, "hello")?;
        let message = ca_certificate(Some(path.clone())).err().map(|e| format!("{e:#}")).unwrap_or_default();
        std::fs::remove_dir_all(&dir)?;
        assert!(message.contains("holds no PEM certificate") && message.ends_with("not-a-ca.pem"), "{message}");
        let missing = ca_certificate(Some(dir.join("nope.pem"))).err().map(|e| format!("{e:#}")).unwrap_or_default();
        assert!(missing.starts_with("cannot read the CA certificate: ") && missing.contains("nope.pem"), "{missing}");
        Ok(())
    }

    #[tokio::test]
    async fn ca_is_for_https_addresses_only() {
        let options = Options { server: "http://127.0.0.1:1", ca: Some(Path::new("ca.pem")), ca_env: None };
        let message = channel(&options).await.err().map(|e| format!("{e:#}")).unwrap_or_default();
        assert!(message.contains("--ca ca.pem is for an https:// server"), "{message}");
    }
}
