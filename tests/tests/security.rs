//! Off loopback: bearer tokens with read and control scopes on every call
//! of both transports, TLS with a CA of the test's own, the refusal to
//! serve a network address open, and no request reading a file the scene
//! does not declare.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

use anyhow::Context;
use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_proto::v1::tile_service_client::TileServiceClient;
use relief_proto::v1::view_service_client::ViewServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::http::{get, request_with};
use relief_tests::probe::{CONTROL, READ, seconds_until_closed, token_file, with_token};
use relief_tests::scenes;
use tonic::Code;
use tonic::transport::{Certificate, Channel, ClientTlsConfig};

async fn state_code(channel: &Channel, token: Option<&str>) -> anyhow::Result<Code> {
    let answer = SceneServiceClient::new(channel.clone()).get_state(with_token(pb::GetStateRequest {}, token)?).await;
    Ok(answer.err().map_or(Code::Ok, |s| s.code()))
}

#[tokio::test]
async fn every_call_needs_a_token_and_only_control_tokens_steer() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = scenes::hill(dir.path(), "")?;
    let tokens = token_file(dir.path())?;
    let daemon = Reliefd::start(&manifest, &["--token-file", &tokens])?;
    let channel = daemon.channel().await?;

    // gRPC: none, wrong, read, control.
    assert_eq!(state_code(&channel, None).await?, Code::Unauthenticated);
    assert_eq!(state_code(&channel, Some("read-0123456789abcdeX")).await?, Code::Unauthenticated);
    assert_eq!(state_code(&channel, Some(READ)).await?, Code::Ok);
    assert_eq!(state_code(&channel, Some(CONTROL)).await?, Code::Ok);
    let tile =
        pb::GetTileRequest { source_id: "dem".into(), key: Some(pb::TileKey { level: 0, x: 0, y: 0 }), quality: None };
    let no_token = TileServiceClient::new(channel.clone()).get_tile(with_token(tile.clone(), None)?).await;
    assert_eq!(no_token.err().map(|s| s.code()), Some(Code::Unauthenticated));
    TileServiceClient::new(channel.clone()).get_tile(with_token(tile, Some(READ))?).await?;

    // A read token cannot reload, move the scene camera or navigate it.
    let mut scene = SceneServiceClient::new(channel.clone());
    let mut view = ViewServiceClient::new(channel.clone());
    let denied = scene.reload(with_token(pb::ReloadRequest::default(), Some(READ))?).await;
    let status = denied.err().context("a read token reloaded")?;
    assert_eq!(status.code(), Code::PermissionDenied);
    assert!(status.message().contains("control token"), "{}", status.message());
    let camera = view.get_camera(with_token(pb::GetCameraRequest {}, Some(READ))?).await?.into_inner();
    let moved = pb::SetCameraRequest { camera: Some(pb::Camera { heading_deg: 90.0, ..camera }) };
    let denied = view.set_camera(with_token(moved, Some(READ))?).await;
    assert_eq!(denied.err().map(|s| s.code()), Some(Code::PermissionDenied));
    let orbit = pb::NavigateRequest {
        view_id: String::new(),
        gesture: Some(pb::navigate_request::Gesture::Orbit(pb::Orbit { heading_deg: 10.0, pitch_deg: 0.0 })),
    };
    let denied = view.navigate(with_token(orbit, Some(READ))?).await;
    assert_eq!(denied.err().map(|s| s.code()), Some(Code::PermissionDenied));
    let unmoved = view.get_camera(with_token(pb::GetCameraRequest {}, Some(READ))?).await?.into_inner();
    assert!((unmoved.heading_deg - camera.heading_deg).abs() < 1e-9, "a refused call moved the camera");

    // A control token can.
    scene.reload(with_token(pb::ReloadRequest::default(), Some(CONTROL))?).await?;
    let set = view.set_camera(with_token(moved, Some(CONTROL))?).await?.into_inner();
    assert!((set.heading_deg - 90.0).abs() < 1e-6);

    // HTTP: the same tokens, the same scopes; the page itself is public.
    let url = daemon.url();
    let codes = tokio::task::spawn_blocking(move || -> anyhow::Result<Vec<u16>> {
        let bearer = |t: &str| format!("Bearer {t}");
        Ok(vec![
            get(&format!("{url}/api/state"))?.status,
            request_with(
                "GET",
                &format!("{url}/api/state"),
                None,
                &[("authorization", &bearer("nope-nope-nope-nope"))],
            )?
            .status,
            request_with("GET", &format!("{url}/api/state"), None, &[("authorization", &bearer(READ))])?.status,
            // A token in the URL is taken only where a browser cannot
            // send a header (event and frame streams, a rendered image).
            get(&format!("{url}/api/state?access_token={READ}"))?.status,
            request_with("POST", &format!("{url}/api/reload?access_token={CONTROL}"), Some("{}"), &[])?.status,
            request_with("POST", &format!("{url}/api/reload"), Some("{}"), &[("authorization", &bearer(READ))])?.status,
            request_with("POST", &format!("{url}/api/reload"), Some("{}"), &[("authorization", &bearer(CONTROL))])?
                .status,
            get(&format!("{url}/"))?.status,
        ])
    })
    .await??;
    assert_eq!(codes, vec![401, 401, 200, 401, 401, 403, 200, 200], "HTTP status codes");
    daemon.stop(&[])?;
    Ok(())
}

/// A CA, and a certificate it signed for localhost and 127.0.0.1:
/// (CA PEM, certificate PEM, key PEM).
fn certificates() -> anyhow::Result<(String, String, String)> {
    let ca_key = rcgen::KeyPair::generate()?;
    let mut ca_params = rcgen::CertificateParams::new(Vec::<String>::new())?;
    ca_params.is_ca = rcgen::IsCa::Ca(rcgen::BasicConstraints::Unconstrained);
    ca_params.distinguished_name.push(rcgen::DnType::CommonName, "relief test CA");
    let ca = ca_params.self_signed(&ca_key)?;
    let key = rcgen::KeyPair::generate()?;
    let params = rcgen::CertificateParams::new(vec!["localhost".to_owned(), "127.0.0.1".to_owned()])?;
    let cert = params.signed_by(&key, &ca, &ca_key)?;
    Ok((ca.pem(), cert.pem(), key.serialize_pem()))
}

/// reliefd serving the hill with the test's tokens and TLS from a CA of
/// the test's own: (the daemon, its port, the CA's PEM, written to `ca.pem` in `dir`).
fn tls_daemon(dir: &Path) -> anyhow::Result<(Reliefd, String, String)> {
    let manifest = scenes::hill(dir, "")?;
    let tokens = token_file(dir)?;
    let (ca, cert, key) = certificates()?;
    let (cert_path, key_path) = (dir.join("server.pem"), dir.join("server.key"));
    std::fs::write(dir.join("ca.pem"), &ca)?;
    std::fs::write(&cert_path, cert)?;
    std::fs::write(&key_path, key)?;
    let (cert_arg, key_arg) = (cert_path.display().to_string(), key_path.display().to_string());
    let daemon = Reliefd::start(&manifest, &["--token-file", &tokens, "--tls-cert", &cert_arg, "--tls-key", &key_arg])?;
    let port = daemon.addr.rsplit(':').next().context("no port")?.to_owned();
    Ok((daemon, port, ca))
}

#[tokio::test]
async fn tls_clients_with_the_ca_are_served_and_plaintext_is_refused() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let (daemon, port, ca) = tls_daemon(dir.path())?;
    let tls = ClientTlsConfig::new().ca_certificate(Certificate::from_pem(ca)).domain_name("localhost");
    let secure = Channel::from_shared(format!("https://localhost:{port}"))?.tls_config(tls)?.connect().await?;
    assert_eq!(state_code(&secure, Some(READ)).await?, Code::Ok);
    assert_eq!(state_code(&secure, None).await?, Code::Unauthenticated);

    // Plaintext gRPC: the handshake fails and the call never reaches a service.
    let plain = Channel::from_shared(format!("http://127.0.0.1:{port}"))?.connect_timeout(Duration::from_secs(5));
    let refused = match plain.connect().await {
        Err(_) => true,
        Ok(channel) => {
            let answer = tokio::time::timeout(Duration::from_secs(10), state_code(&channel, Some(READ))).await;
            !matches!(answer, Ok(Ok(Code::Ok)))
        }
    };
    assert!(refused, "a plaintext client was served by a TLS port");
    // Plaintext HTTP/1.1 gets no HTTP answer.
    let url = format!("http://127.0.0.1:{port}/api/state?access_token={READ}");
    let http = tokio::task::spawn_blocking(move || get(&url)).await?;
    assert!(http.is_err() || http.is_ok_and(|r| r.status != 200), "plaintext HTTP was served by a TLS port");
    let log = daemon.stop(&[])?;
    assert!(log.iter().any(|l| l.contains("TLS handshake failed")), "the refusal is logged");
    Ok(())
}

/// Finding 5 of issue 36 over TLS: a client that completes the handshake
/// and then sends nothing, or its headers a byte a second, is closed
/// within the 10 s deadline.
#[test]
fn a_slowloris_connection_over_tls_is_closed_within_the_header_timeout() -> anyhow::Result<()> {
    use rustls::pki_types::pem::PemObject;
    let dir = tempfile::tempdir()?;
    let (daemon, port, ca) = tls_daemon(dir.path())?;
    let mut roots = rustls::RootCertStore::empty();
    roots.add(rustls::pki_types::CertificateDer::from_pem_slice(ca.as_bytes())?)?;
    let config = std::sync::Arc::new(
        rustls::ClientConfig::builder_with_provider(std::sync::Arc::new(rustls::crypto::ring::default_provider()))
            .with_safe_default_protocol_versions()?
            .with_root_certificates(roots)
            .with_no_client_auth(),
    );
    let drip = |bytes: &'static [u8]| -> anyhow::Result<Option<f64>> {
        let name = rustls::pki_types::ServerName::try_from("localhost")?;
        let tcp = std::net::TcpStream::connect(format!("127.0.0.1:{port}"))?;
        tcp.set_read_timeout(Some(Duration::from_secs(1)))?;
        let mut tls = rustls::StreamOwned::new(rustls::ClientConnection::new(config.clone(), name)?, tcp);
        while tls.conn.is_handshaking() {
            tls.conn.complete_io(&mut tls.sock)?;
        }
        Ok(seconds_until_closed(&mut tls, bytes, Duration::from_secs(20)))
    };
    let silent = std::thread::scope(|s| {
        let silent = s.spawn(|| drip(b""));
        let dripping = drip(b"GET /api/state HTTP/1.1\r\nHost: localhost\r\nX-Slow: aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa");
        (silent.join(), dripping)
    });
    let (silent, dripping) = (silent.0.map_err(|_| anyhow::anyhow!("the silent client panicked"))??, silent.1?);
    assert!(dripping.is_some_and(|s| s < 13.0), "a byte a second kept it open: {dripping:?}");
    assert!(silent.is_some_and(|s| s < 13.0), "silence after the handshake kept it open: {silent:?}");
    daemon.stop(&[])?;
    Ok(())
}

/// `reliefd serve MANIFEST --listen ADDR ...` until it prints its address
/// (then stopped) or exits: (exit code if it exited, all it wrote).
fn serve_once(manifest: &Path, listen: &str, extra: &[&str]) -> anyhow::Result<(Option<i32>, String)> {
    use std::io::{BufRead, BufReader, Read};
    let mut child = Command::new(relief_tests::bin("reliefd"))
        .arg("serve")
        .arg(manifest)
        .args(["--listen", listen])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()?;
    let stdout = child.stdout.take().context("no stdout")?;
    let mut stderr = child.stderr.take().context("no stderr")?;
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::Builder::new().name("reliefd-stdout".into()).spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    })?;
    let err = std::thread::Builder::new().name("reliefd-stderr".into()).spawn(move || {
        let mut text = String::new();
        let _ = stderr.read_to_string(&mut text);
        text
    })?;
    let mut printed = String::new();
    let mut serving = false;
    for _ in 0..600 {
        while let Ok(line) = rx.try_recv() {
            serving |= line.starts_with("listening on ");
            printed.push_str(&line);
            printed.push('\n');
        }
        if serving || child.try_wait()?.is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    if serving {
        let _ = child.kill();
    }
    let status = child.wait()?;
    let text = format!("{printed}{}", err.join().unwrap_or_default());
    Ok((if serving { None } else { status.code() }, text))
}

#[test]
fn a_network_address_is_not_served_open_unless_asked() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = scenes::hill(dir.path(), "")?;
    let (code, text) = serve_once(&manifest, "0.0.0.0:0", &[])?;
    assert_eq!(code, Some(1), "{text}");
    assert!(text.contains("refusing to serve 0.0.0.0:0 without a token file (--token-file) and TLS"), "{text}");
    assert!(text.contains("--insecure"), "{text}");
    // A token alone is not enough.
    let tokens = token_file(dir.path())?;
    let (code, text) = serve_once(&manifest, "0.0.0.0:0", &["--token-file", &tokens])?;
    assert_eq!(code, Some(1), "{text}");
    assert!(text.contains("without TLS (--tls-cert, --tls-key)"), "{text}");
    // --insecure serves, and says so.
    let (code, text) = serve_once(&manifest, "0.0.0.0:0", &["--insecure"])?;
    assert_eq!(code, None, "{text}");
    assert!(text.contains("listening on 0.0.0.0:"), "{text}");
    assert!(text.contains("WARN") && text.contains("(--insecure)"), "{text}");
    // A bad token file is named.
    std::fs::write(dir.path().join("bad-tokens"), "admin 0123456789abcdef0123\n")?;
    let bad = dir.path().join("bad-tokens").display().to_string();
    let (code, text) = serve_once(&manifest, "127.0.0.1:0", &["--token-file", &bad])?;
    assert_eq!(code, Some(1), "{text}");
    assert!(text.contains("cannot use the token file: line 1: unknown scope 'admin'") && text.contains(&bad), "{text}");
    Ok(())
}

#[tokio::test]
async fn no_request_reads_a_file_the_scene_does_not_declare() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = scenes::hill(dir.path(), "")?;
    let secret = dir.path().join("secret.txt");
    std::fs::write(&secret, "the-secret-words")?;
    let daemon = Reliefd::start(&manifest, &[])?;
    let channel = daemon.channel().await?;
    let secret_path = secret.display().to_string();
    for source_id in ["../secret.txt", secret_path.as_str(), "/etc/passwd", "dem/../../secret.txt"] {
        let request = pb::GetTileRequest {
            source_id: source_id.into(),
            key: Some(pb::TileKey { level: 0, x: 0, y: 0 }),
            quality: None,
        };
        let status = TileServiceClient::new(channel.clone()).get_tile(request).await.err().context("served")?;
        assert_eq!(status.code(), Code::NotFound, "{source_id}: {}", status.message());
        let sample = pb::SampleElevationRequest {
            points: vec![pb::GeodeticPoint { lon_deg: 10.25, lat_deg: 45.15 }],
            source_id: source_id.into(),
        };
        let status = TileServiceClient::new(channel.clone()).sample_elevation(sample).await.err().context("sampled")?;
        assert_eq!(status.code(), Code::NotFound, "{source_id}: {}", status.message());
    }
    let url = daemon.url();
    let bodies = tokio::task::spawn_blocking(move || -> anyhow::Result<Vec<(u16, String)>> {
        let mut out = Vec::new();
        for path in [
            "/../secret.txt",
            "/%2e%2e/secret.txt",
            "/api/tiles/..%2Fsecret.txt/0/0/0",
            "/api/tiles/%2Fetc%2Fpasswd/0/0/0",
            "/secret.txt",
            "/index.html/../secret.txt",
        ] {
            let r = get(&format!("{url}{path}"))?;
            out.push((r.status, String::from_utf8_lossy(&r.body).into_owned()));
        }
        Ok(out)
    })
    .await??;
    for (status, body) in bodies {
        assert!(status == 404 || status == 400, "{status}: {body}");
        assert!(!body.contains("the-secret-words") && !body.contains("root:"), "{body}");
    }
    daemon.stop(&[])?;
    Ok(())
}

/// `relief ARGS` against `port` over TLS with the environment cleared of
/// tokens and CAs: (exit code, stderr).
fn cli(args: &[&str], env: &[(&str, &str)]) -> anyhow::Result<(i32, String)> {
    let mut command = Command::new(relief_tests::bin("relief"));
    command.env_remove("RELIEF_TOKEN").env_remove("RELIEF_CA").env_remove("RELIEF_SERVER").args(args);
    for (k, v) in env {
        command.env(k, v);
    }
    let out = command.output()?;
    Ok((out.status.code().unwrap_or(-1), String::from_utf8_lossy(&out.stderr).into_owned()))
}

#[tokio::test]
async fn the_cli_sends_its_token_over_tls_and_says_plainly_when_refused() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let (daemon, port, _) = tls_daemon(dir.path())?;
    let https = format!("https://localhost:{port}");
    let ca = dir.path().join("ca.pem").display().to_string();
    let set = ["camera", "set", "10.25,45.1,9000,30,-45,0"];
    let outcomes = tokio::task::spawn_blocking(move || -> anyhow::Result<Vec<(i32, String)>> {
        let with = |extra: &[&str]| -> Vec<String> {
            ["--server", https.as_str()].iter().chain(extra).map(|s| (*s).to_owned()).collect()
        };
        let run = |args: Vec<String>, env: &[(&str, &str)]| {
            let args: Vec<&str> = args.iter().map(String::as_str).collect();
            cli(&args, env)
        };
        let plain = format!("http://127.0.0.1:{port}");
        Ok(vec![
            run(with(&["--ca", &ca, "state"]), &[])?,
            run(with(&["--ca", &ca, "--token", READ, "state"]), &[])?,
            run(with(&set), &[("RELIEF_TOKEN", READ), ("RELIEF_CA", &ca)])?,
            run(with(&[&["--ca", ca.as_str(), "--token", CONTROL][..], &set[..]].concat()), &[])?,
            run(with(&["--token", READ, "state"]), &[])?,
            cli(&["--server", &plain, "--token", READ, "state"], &[])?,
        ])
    })
    .await??;
    let [none, read, steer_read, steer_control, no_ca, plaintext] = outcomes.as_slice() else {
        anyhow::bail!("six outcomes expected")
    };
    assert_eq!(none.0, 1, "{}", none.1);
    assert!(none.1.contains("refused the call: missing token") && none.1.contains("(UNAUTHENTICATED)"), "{}", none.1);
    assert_eq!(read.0, 0, "{}", read.1);
    assert_eq!(steer_read.0, 1, "{}", steer_read.1);
    assert!(steer_read.1.contains("(PERMISSION_DENIED)") && steer_read.1.contains("control token"), "{}", steer_read.1);
    assert_eq!(steer_control.0, 0, "{}", steer_control.1);
    assert_ne!(no_ca.0, 0, "a server signed by an unknown CA was trusted");
    assert!(no_ca.1.contains("over TLS"), "{}", no_ca.1);
    assert_ne!(plaintext.0, 0);
    assert!(plaintext.1.contains("https://"), "{}", plaintext.1);
    for (_, stderr) in &outcomes {
        assert!(!stderr.contains("{ ") && !stderr.contains("Some("), "Debug output: {stderr}");
    }
    daemon.stop(&[])?;
    Ok(())
}
