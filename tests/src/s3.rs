//! Object storage for the tests of sources on S3 and HTTPS (issue 41), on
//! real servers: [`S3Server`] is moto in server mode (PyPI `moto[server]`,
//! pinned in `scripts/setup.sh`, which installs it into the venv
//! `target/s3`), and [`HttpServer`] is npm's `http-server` (from
//! `tests/npm`'s lockfile), standing in for a public HTTPS host of COGs read
//! over `/vsicurl/`. Each runs on a free loopback port and is stopped when
//! dropped.
//!
//! The harness signs its own S3 requests with AWS Signature Version 4
//! (ring's HMAC-SHA256): moto answers an unsigned GET, HEAD or DELETE with
//! 403 (an anonymous caller on a private bucket), and once keys are checked
//! ([`S3Server::refuse_unknown_keys`]) it recomputes every signature with
//! botocore, so each test in that mode checks the signing too.

use std::fmt::Write as _;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use anyhow::{Context, bail, ensure};

/// The access key id [`S3Server::env`] hands a reliefd. moto holds no such
/// key, so once it checks keys it refuses this one.
pub const ACCESS_KEY_ID: &str = "AKIARELIEFTESTKEY001";
/// The secret [`S3Server::env`] hands a reliefd: a test may grep any output
/// (logs, state, metrics, errors) for it, and must not find it.
pub const SECRET_ACCESS_KEY: &str = "relief-test-secret-DO-NOT-LEAK";
/// The region every request is signed for.
pub const REGION: &str = "us-east-1";

/// How long a server may take to start answering (moto imports for 1-2 s).
const START_WAIT: Duration = Duration::from_secs(30);

/// What `HEAD` says of an object: its version, as relief's poller sees it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ObjectHead {
    /// As sent, quotes included: moto's is the MD5 of the bytes in hex.
    pub etag: String,
    pub len: u64,
    /// As sent (an HTTP date, to the second).
    pub last_modified: String,
}

/// moto's S3 on `127.0.0.1`, in one process with its own state: buckets
/// and objects live in its memory and are gone when it is dropped.
///
/// moto starts accepting any key and any signature. In that mode a reliefd
/// given [`S3Server::env`] reads and polls as it would on AWS. After
/// [`S3Server::refuse_unknown_keys`] (or from the start, with
/// [`S3Server::start_with_auth`]) moto checks keys and signatures, and
/// refuses the test key with 403 `InvalidAccessKeyId` ("The AWS Access Key
/// Id you provided does not exist in our records."); the harness itself
/// keeps working, with a key moto issued. [`S3Server::accept_any_keys`]
/// turns that back off, so a test can show credentials refused and then
/// accepted again, on one server.
pub struct S3Server {
    server: Server,
    /// The key the harness signs with: an IAM user's, made at start with an
    /// allow-all policy, so it stays valid when moto checks keys.
    harness_key: Key,
}

impl S3Server {
    /// Starts `target/s3/bin/moto_server` on a free port (moto binds port
    /// 0 and prints the one it got) and makes the harness's own IAM user.
    /// Fails, saying to run `bash scripts/setup.sh`, when moto is not
    /// installed.
    pub fn start() -> anyhow::Result<Self> {
        let moto = moto_server();
        ensure!(
            moto.exists(),
            "no moto server at {}: run `bash scripts/setup.sh` (make test does) to install moto[server] into target/s3",
            moto.display()
        );
        let mut command = Command::new(&moto);
        command.args(["-H", "127.0.0.1", "-p", "0"]);
        // Keys are never checked until a test asks (moto's default, said
        // here so an INITIAL_NO_AUTH_ACTION_COUNT in the test's own
        // environment cannot change it).
        command.env("INITIAL_NO_AUTH_ACTION_COUNT", "inf");
        let server = Server::spawn(command, "moto_server", |line| {
            // Werkzeug: " * Running on http://127.0.0.1:PORT"
            line.split("Running on http://127.0.0.1:").nth(1).and_then(|rest| rest.trim().parse().ok())
        })?;
        let bootstrap = Key { id: ACCESS_KEY_ID.into(), secret: SECRET_ACCESS_KEY.into() };
        let mut s3 = Self { server, harness_key: bootstrap };
        s3.harness_key = s3.make_harness_user().context("cannot make the harness's IAM user in moto")?;
        Ok(s3)
    }

    /// [`S3Server::start`], then [`S3Server::refuse_unknown_keys`]: every
    /// request signed with [`S3Server::env`]'s key is refused with 403
    /// `InvalidAccessKeyId`, while the harness's own calls
    /// ([`S3Server::create_bucket`], [`S3Server::put`], ...) work.
    pub fn start_with_auth() -> anyhow::Result<Self> {
        let s3 = Self::start()?;
        s3.refuse_unknown_keys()?;
        Ok(s3)
    }

    /// From now on moto checks each request's key and signature: keys it
    /// did not issue get 403 `InvalidAccessKeyId`, a bad signature 403
    /// `SignatureDoesNotMatch`, an unsigned request 403 with no body. This
    /// is moto's `/moto-api/reset-auth` with 0 (the runtime form of its
    /// `INITIAL_NO_AUTH_ACTION_COUNT`, which counts every request from any
    /// client, so a count set at start would depend on how many requests a
    /// reliefd happened to make).
    pub fn refuse_unknown_keys(&self) -> anyhow::Result<()> {
        self.reset_auth("0")
    }

    /// Back to accepting any key and any signature.
    pub fn accept_any_keys(&self) -> anyhow::Result<()> {
        self.reset_auth("inf")
    }

    pub fn port(&self) -> u16 {
        self.server.port
    }

    /// `http://127.0.0.1:PORT`, the value of `AWS_ENDPOINT_URL`.
    pub fn endpoint(&self) -> String {
        format!("http://127.0.0.1:{}", self.server.port)
    }

    /// The standard AWS environment a reliefd needs to reach this server
    /// with the test key: `AWS_ENDPOINT_URL`, `AWS_ACCESS_KEY_ID`,
    /// `AWS_SECRET_ACCESS_KEY` ([`SECRET_ACCESS_KEY`]) and `AWS_REGION`.
    pub fn env(&self) -> Vec<(String, String)> {
        with_test_key(vec![("AWS_ENDPOINT_URL".into(), self.endpoint())])
    }

    /// GDAL's own configuration options for the same (GDAL 3.6 does not
    /// read `AWS_ENDPOINT_URL`), for a test that reads `/vsis3/` in
    /// process: `AWS_S3_ENDPOINT=127.0.0.1:PORT`, `AWS_HTTPS=NO`,
    /// `AWS_VIRTUAL_HOSTING=FALSE` and the test key.
    pub fn gdal_config(&self) -> Vec<(String, String)> {
        with_test_key(vec![
            ("AWS_S3_ENDPOINT".into(), format!("127.0.0.1:{}", self.server.port)),
            ("AWS_HTTPS".into(), "NO".into()),
            ("AWS_VIRTUAL_HOSTING".into(), "FALSE".into()),
        ])
    }

    /// Every line moto has printed: one per request
    /// (`127.0.0.1 - - [date] "GET /bucket/key HTTP/1.1" 206 -`), so a test
    /// can count the HEADs or ranged GETs a reliefd made.
    pub fn log(&self) -> Vec<String> {
        self.server.log()
    }

    pub fn create_bucket(&self, bucket: &str) -> anyhow::Result<()> {
        let reply = self.s3("PUT", &format!("/{bucket}"), &[])?;
        reply.ok(&format!("cannot create bucket '{bucket}'"))
    }

    /// Writes (or overwrites) an object in one PUT; returns its ETag.
    pub fn put(&self, bucket: &str, key: &str, bytes: &[u8]) -> anyhow::Result<String> {
        let reply = self.s3("PUT", &format!("/{bucket}/{key}"), bytes)?;
        reply.ok(&format!("cannot put s3://{bucket}/{key}"))?;
        reply.header("etag").map(str::to_owned).with_context(|| format!("moto sent no ETag for s3://{bucket}/{key}"))
    }

    /// Writes an object anyone may read (the canned ACL `public-read`, as
    /// a public bucket's objects are): an unsigned GET or HEAD reads it.
    pub fn put_public(&self, bucket: &str, key: &str, path: &Path) -> anyhow::Result<()> {
        let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
        let host = format!("127.0.0.1:{}", self.server.port);
        let path = uri_encode(&format!("/{bucket}/{key}"), true);
        let mut headers = sign(&self.harness_key, "PUT", &host, &path, "s3", &bytes, SystemTime::now());
        // Not signed: moto checks no signature while keys are not checked.
        headers.push(("x-amz-acl".to_owned(), "public-read".to_owned()));
        let reply = send("PUT", &format!("http://{host}{path}"), &headers, "application/octet-stream", &bytes)?;
        reply.ok(&format!("cannot put s3://{bucket}/{key}"))
    }

    /// [`S3Server::put`] with a file's bytes.
    pub fn put_file(&self, bucket: &str, key: &str, path: &Path) -> anyhow::Result<String> {
        let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
        self.put(bucket, key, &bytes)
    }

    /// Deletes an object (S3 says yes to deleting one that is not there).
    pub fn delete(&self, bucket: &str, key: &str) -> anyhow::Result<()> {
        let reply = self.s3("DELETE", &format!("/{bucket}/{key}"), &[])?;
        reply.ok(&format!("cannot delete s3://{bucket}/{key}"))
    }

    /// An object's ETag, size and Last-Modified; None when it is not there.
    pub fn head(&self, bucket: &str, key: &str) -> anyhow::Result<Option<ObjectHead>> {
        let reply = self.s3("HEAD", &format!("/{bucket}/{key}"), &[])?;
        if reply.status == 404 {
            return Ok(None);
        }
        reply.ok(&format!("cannot HEAD s3://{bucket}/{key}"))?;
        let header = |name: &str| {
            reply
                .header(name)
                .map(str::to_owned)
                .with_context(|| format!("moto's HEAD of s3://{bucket}/{key} has no {name}"))
        };
        Ok(Some(ObjectHead {
            etag: header("etag")?,
            len: header("content-length")?.parse().context("moto's content-length is not a number")?,
            last_modified: header("last-modified")?,
        }))
    }

    /// An object's bytes; None when it is not there.
    pub fn get(&self, bucket: &str, key: &str) -> anyhow::Result<Option<Vec<u8>>> {
        let reply = self.s3("GET", &format!("/{bucket}/{key}"), &[])?;
        if reply.status == 404 {
            return Ok(None);
        }
        reply.ok(&format!("cannot GET s3://{bucket}/{key}"))?;
        Ok(Some(reply.body))
    }

    /// One S3 request for `path` (`/bucket/key`), signed with the harness's
    /// key. Bodies go as `application/octet-stream`: Werkzeug reads a body
    /// sent as a form (curl's default) into form fields, and moto then
    /// stores an empty object.
    fn s3(&self, method: &str, path: &str, body: &[u8]) -> anyhow::Result<Reply> {
        let host = format!("127.0.0.1:{}", self.server.port);
        let path = uri_encode(path, true);
        let headers = sign(&self.harness_key, method, &host, &path, "s3", body, SystemTime::now());
        send(method, &format!("http://{host}{path}"), &headers, "application/octet-stream", body)
    }

    /// One IAM query-API call (POST of a form to `/`; moto routes it to IAM
    /// by the signature's scope). Only made while keys are not checked.
    fn iam(&self, params: &[(&str, &str)]) -> anyhow::Result<String> {
        let host = format!("127.0.0.1:{}", self.server.port);
        let body = params
            .iter()
            .chain(&[("Version", "2010-05-08")])
            .map(|(k, v)| format!("{k}={}", uri_encode(v, false)))
            .collect::<Vec<_>>()
            .join("&");
        let headers = sign(&self.harness_key, "POST", &host, "/", "iam", body.as_bytes(), SystemTime::now());
        let reply =
            send("POST", &format!("http://{host}/"), &headers, "application/x-www-form-urlencoded", body.as_bytes())?;
        reply.ok(&format!("IAM {}", params.first().map_or("", |(_, v)| *v)))?;
        Ok(String::from_utf8_lossy(&reply.body).into_owned())
    }

    /// An IAM user allowed everything, and a key of its own.
    fn make_harness_user(&self) -> anyhow::Result<Key> {
        let user = "relief-test-harness";
        self.iam(&[("Action", "CreateUser"), ("UserName", user)])?;
        let policy = r#"{"Version":"2012-10-17","Statement":[{"Effect":"Allow","Action":"*","Resource":"*"}]}"#;
        self.iam(&[
            ("Action", "PutUserPolicy"),
            ("UserName", user),
            ("PolicyName", "all"),
            ("PolicyDocument", policy),
        ])?;
        let xml = self.iam(&[("Action", "CreateAccessKey"), ("UserName", user)])?;
        let tag = |name: &str| {
            xml.split(&format!("<{name}>"))
                .nth(1)
                .and_then(|rest| rest.split(&format!("</{name}>")).next())
                .map(str::to_owned)
                .with_context(|| format!("no {name} in moto's CreateAccessKey answer: {xml}"))
        };
        Ok(Key { id: tag("AccessKeyId")?, secret: tag("SecretAccessKey")? })
    }

    fn reset_auth(&self, count: &str) -> anyhow::Result<()> {
        let url = format!("{}/moto-api/reset-auth", self.endpoint());
        // Not a form (see `s3`): moto reads the number from the raw body.
        send("POST", &url, &[], "text/plain", count.as_bytes())?.ok("cannot switch moto's key checks")
    }
}

/// npm's `http-server` serving a folder on `127.0.0.1`, as a public HTTPS
/// host of COGs would be read through `/vsicurl/` (plain HTTP: the tests
/// hold no certificate a reliefd would trust).
///
/// It answers a single `Range: bytes=A-B` with 206 and `Content-Range`,
/// and sends `ETag` and `Last-Modified` on every answer (200, 206, HEAD).
/// Its ETag is weak, `W/"INODE-SIZE-MTIME"` with the modification time to
/// the millisecond, so it changes when a file is rewritten, unless the
/// rewrite keeps the size and lands in the same millisecond. It is run with
/// `-c-1` (`cache-control: no-cache, no-store, must-revalidate`), since the
/// tests rewrite its files, and without directory listings. It does not
/// answer suffix (`bytes=-N`) or multiple ranges as a full server would:
/// GDAL asks for neither.
pub struct HttpServer {
    server: Server,
    dir: PathBuf,
}

impl HttpServer {
    /// Serves `dir` on a free port. `http-server` takes the port it is
    /// given (with 0 it searches upward from 8080, which races other
    /// tests), so a free one is picked here and a start that lost it to
    /// another process is tried again.
    pub fn start(dir: &Path) -> anyhow::Result<Self> {
        // Not `npm::available`, which says the test is skipped: it fails.
        let node = Command::new("node").arg("--version").output().is_ok_and(|o| o.status.success());
        ensure!(
            node,
            "no node for npm's http-server: run `bash scripts/setup.sh` to install node and npm (CI has them)"
        );
        let bin = crate::npm::node_modules()?.join(".bin/http-server");
        ensure!(bin.exists(), "no {} after npm ci: is http-server in tests/npm/package.json?", bin.display());
        let mut last_error = None;
        for _ in 0..3 {
            let port = free_port()?;
            let mut command = Command::new(&bin);
            command.arg(dir).args(["-a", "127.0.0.1", "-p", &port.to_string(), "-c-1", "-d", "false"]);
            let wanted = format!("http://127.0.0.1:{port}");
            match Server::spawn(command, "http-server", move |line| line.contains(&wanted).then_some(port)) {
                Ok(server) => return Ok(Self { server, dir: dir.to_path_buf() }),
                Err(e) => last_error = Some(e),
            }
        }
        Err(last_error.expect("three tries were made"))
    }

    /// `http://127.0.0.1:PORT/` followed by `path` (relative to the folder).
    pub fn url(&self, path: &str) -> String {
        format!("http://127.0.0.1:{}/{}", self.server.port, path.trim_start_matches('/'))
    }

    pub fn port(&self) -> u16 {
        self.server.port
    }

    /// The folder it serves.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Every line it has printed: one per request.
    pub fn log(&self) -> Vec<String> {
        self.server.log()
    }

    /// `url(path)`'s ETag, size and Last-Modified from a HEAD; None on 404.
    pub fn head(&self, path: &str) -> anyhow::Result<Option<ObjectHead>> {
        let url = self.url(path);
        let reply = send("HEAD", &url, &[], "", &[])?;
        if reply.status == 404 {
            return Ok(None);
        }
        reply.ok(&format!("cannot HEAD {url}"))?;
        let header =
            |name: &str| reply.header(name).map(str::to_owned).with_context(|| format!("HEAD {url} has no {name}"));
        Ok(Some(ObjectHead {
            etag: header("etag")?,
            len: header("content-length")?.parse().context("http-server's content-length is not a number")?,
            last_modified: header("last-modified")?,
        }))
    }
}

/// A child process whose stdout and stderr are read into a log, killed
/// when dropped.
struct Server {
    child: Child,
    port: u16,
    log: Arc<Mutex<Vec<String>>>,
}

impl Server {
    /// Starts `command` and waits for a line of its output from which
    /// `ready` reads the port it listens on.
    fn spawn(
        mut command: Command,
        name: &str,
        ready: impl Fn(&str) -> Option<u16> + Send + Sync + 'static,
    ) -> anyhow::Result<Self> {
        let mut child = command
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .with_context(|| format!("cannot start {name} (scripts/setup.sh installs it)"))?;
        let log = Arc::new(Mutex::new(Vec::new()));
        let ready = Arc::new(ready);
        let (tx, rx) = mpsc::sync_channel(2);
        let outputs: [Box<dyn Read + Send>; 2] =
            [Box::new(child.stdout.take().context("no stdout")?), Box::new(child.stderr.take().context("no stderr")?)];
        for output in outputs {
            let (log, ready, tx) = (Arc::clone(&log), Arc::clone(&ready), tx.clone());
            // Read to the end, not only to the port: a server whose pipe
            // fills stops answering.
            std::thread::Builder::new().name(format!("{name}-output")).spawn(move || {
                let mut reader = BufReader::new(output);
                let mut line = Vec::new();
                while reader.read_until(b'\n', &mut line).is_ok_and(|n| n > 0) {
                    let text = String::from_utf8_lossy(&line).trim_end().to_owned();
                    if let Some(port) = ready(&text) {
                        let _ = tx.try_send(port);
                    }
                    log.lock().expect("log lock").push(text);
                    line.clear();
                }
            })?;
        }
        drop(tx);
        let mut server = Self { child, port: 0, log };
        match rx.recv_timeout(START_WAIT) {
            Ok(port) => {
                server.port = port;
                Ok(server)
            }
            // Both outputs closed (it exited) or it said nothing in time;
            // dropping `server` kills it.
            Err(_) => bail!("{name} did not start listening on loopback: {}", server.log().join("\n")),
        }
    }

    fn log(&self) -> Vec<String> {
        self.log.lock().expect("log lock").clone()
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `settings` and the test key and region after them.
fn with_test_key(mut settings: Vec<(String, String)>) -> Vec<(String, String)> {
    settings.extend([
        ("AWS_ACCESS_KEY_ID".into(), ACCESS_KEY_ID.into()),
        ("AWS_SECRET_ACCESS_KEY".into(), SECRET_ACCESS_KEY.into()),
        ("AWS_REGION".into(), REGION.into()),
    ]);
    settings
}

/// `target/s3/bin/moto_server`, which scripts/setup.sh installs.
pub fn moto_server() -> PathBuf {
    crate::workspace_root().join("target/s3/bin/moto_server")
}

/// A loopback port nothing listens on now.
fn free_port() -> anyhow::Result<u16> {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").context("cannot listen on loopback")?;
    Ok(listener.local_addr()?.port())
}

struct Key {
    id: String,
    secret: String,
}

struct Reply {
    status: u16,
    headers: Vec<(String, String)>,
    body: Vec<u8>,
}

impl Reply {
    fn header(&self, name: &str) -> Option<&str> {
        self.headers.iter().find(|(n, _)| n.eq_ignore_ascii_case(name)).map(|(_, v)| v.as_str())
    }

    /// Err with `what`, the status and S3's error XML unless it is a 2xx.
    fn ok(&self, what: &str) -> anyhow::Result<()> {
        ensure!((200..300).contains(&self.status), "{what}: {} {}", self.status, String::from_utf8_lossy(&self.body));
        Ok(())
    }
}

fn send(
    method: &str,
    url: &str,
    headers: &[(String, String)],
    content_type: &str,
    body: &[u8],
) -> anyhow::Result<Reply> {
    let agent: ureq::Agent = ureq::Agent::config_builder().http_status_as_error(false).build().into();
    let response = match method {
        "GET" | "HEAD" | "DELETE" => {
            let mut request = match method {
                "GET" => agent.get(url),
                "HEAD" => agent.head(url),
                _ => agent.delete(url),
            };
            for (n, v) in headers {
                request = request.header(n, v);
            }
            request.call()
        }
        "PUT" | "POST" => {
            let mut request = if method == "PUT" { agent.put(url) } else { agent.post(url) };
            for (n, v) in headers {
                request = request.header(n, v);
            }
            request.content_type(content_type).send(body)
        }
        m => bail!("no such method in this client: {m}"),
    }
    .with_context(|| format!("{method} {url}"))?;
    let status = response.status().as_u16();
    let headers =
        response.headers().iter().map(|(n, v)| (n.to_string(), v.to_str().unwrap_or_default().to_owned())).collect();
    let body = response.into_body().with_config().limit(1 << 30).read_to_vec()?;
    Ok(Reply { status, headers, body })
}

/// The headers that sign a request with AWS Signature Version 4 (host,
/// payload hash and date signed): `x-amz-date`, `x-amz-content-sha256` and
/// `authorization`. `path` is already URI-encoded; no query string.
fn sign(
    key: &Key,
    method: &str,
    host: &str,
    path: &str,
    service: &str,
    body: &[u8],
    now: SystemTime,
) -> Vec<(String, String)> {
    use ring::{digest, hmac};
    let hex = |bytes: &[u8]| {
        bytes.iter().fold(String::with_capacity(2 * bytes.len()), |mut out, b| {
            let _ = write!(out, "{b:02x}");
            out
        })
    };
    let amz_date = amz_date(now);
    let date = &amz_date[..8];
    let payload = hex(digest::digest(&digest::SHA256, body).as_ref());
    let signed_headers = "host;x-amz-content-sha256;x-amz-date";
    let canonical = format!(
        "{method}\n{path}\n\nhost:{host}\nx-amz-content-sha256:{payload}\nx-amz-date:{amz_date}\n\n{signed_headers}\n{payload}"
    );
    let scope = format!("{date}/{REGION}/{service}/aws4_request");
    let to_sign = format!(
        "AWS4-HMAC-SHA256\n{amz_date}\n{scope}\n{}",
        hex(digest::digest(&digest::SHA256, canonical.as_bytes()).as_ref())
    );
    let mac = |key: &[u8], data: &str| hmac::sign(&hmac::Key::new(hmac::HMAC_SHA256, key), data.as_bytes());
    let k_date = mac(format!("AWS4{}", key.secret).as_bytes(), date);
    let k_region = mac(k_date.as_ref(), REGION);
    let k_service = mac(k_region.as_ref(), service);
    let k_signing = mac(k_service.as_ref(), "aws4_request");
    let signature = hex(mac(k_signing.as_ref(), &to_sign).as_ref());
    vec![
        ("x-amz-date".into(), amz_date.clone()),
        ("x-amz-content-sha256".into(), payload),
        (
            "authorization".into(),
            format!(
                "AWS4-HMAC-SHA256 Credential={}/{scope}, SignedHeaders={signed_headers}, Signature={signature}",
                key.id
            ),
        ),
    ]
}

/// `YYYYMMDDTHHMMSSZ` in UTC (the civil date from days since 1970 by
/// Howard Hinnant's `civil_from_days`).
fn amz_date(now: SystemTime) -> String {
    let secs = now.duration_since(UNIX_EPOCH).expect("the clock is after 1970").as_secs();
    let (days, rem) = ((secs / 86_400) as i64, secs % 86_400);
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}{month:02}{day:02}T{:02}{:02}{:02}Z", rem / 3600, rem % 3600 / 60, rem % 60)
}

/// AWS's URI encoding: every byte but `A-Za-z0-9-._~` as `%XX`, and `/`
/// too unless `keep_slash` (a path).
fn uri_encode(s: &str, keep_slash: bool) -> String {
    let mut out = String::with_capacity(s.len());
    for b in s.bytes() {
        if b.is_ascii_alphanumeric() || b"-._~".contains(&b) || (keep_slash && b == b'/') {
            out.push(b as char);
        } else {
            let _ = write!(out, "%{b:02X}");
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn amz_date_is_utc_civil_time() {
        assert_eq!(amz_date(UNIX_EPOCH), "19700101T000000Z");
        assert_eq!(amz_date(UNIX_EPOCH + Duration::from_secs(1_700_000_000)), "20231114T221320Z");
        // 2024-02-29 (a leap day) 23:59:59
        assert_eq!(amz_date(UNIX_EPOCH + Duration::from_secs(1_709_251_199)), "20240229T235959Z");
    }

    // The signatures themselves are checked by moto, with botocore, in
    // tests/object_harness.rs (keys checked, so a wrong one is refused).
    #[test]
    fn uri_encoding_keeps_unreserved_bytes() {
        assert_eq!(uri_encode("/b/dem v2.tif", true), "/b/dem%20v2.tif");
        assert_eq!(uri_encode("a/b", false), "a%2Fb");
    }
}
