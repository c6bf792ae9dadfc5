//! A real reliefd process on 127.0.0.1, for tests.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex, mpsc};
use std::time::Duration;

use anyhow::{Context, bail};
use tonic::transport::Channel;

/// How long a stopped reliefd's log may take to reach its last line.
const LOG_END_WAIT: Duration = Duration::from_secs(5);

/// A running reliefd. Dropping it kills the process; `stop` shuts it down
/// gracefully and returns what it logged.
pub struct Reliefd {
    child: Child,
    pub addr: String,
    log: Arc<Mutex<Vec<String>>>,
    /// Told when the log's reader has read the last line (stderr closed).
    log_ended: Mutex<mpsc::Receiver<()>>,
    /// Every line it printed on stdout.
    printed: Arc<Mutex<Vec<String>>>,
    /// Its user cache folder (the disk tile cache's default home): one per
    /// daemon, so no test reads tiles another test left.
    _cache: tempfile::TempDir,
}

impl Reliefd {
    /// Starts `reliefd serve MANIFEST --listen 127.0.0.1:0` (unless `extra`
    /// names another `--listen`) and waits for its `listening on ADDR` line. With RELIEF_DAEMON_WRAP set, reliefd
    /// runs under that command (words split on whitespace), for a profiler:
    /// `env LD_PRELOAD=... VAR=...` keeps reliefd's own process id, which
    /// `pid` and the benches' resident sets read.
    pub fn start(manifest: &Path, extra: &[&str]) -> anyhow::Result<Self> {
        Self::start_with_env(manifest, extra, &[])
    }

    /// `start`, with `env` added to reliefd's environment (the AWS
    /// variables of an object store, say).
    pub fn start_with_env(manifest: &Path, extra: &[&str], env: &[(String, String)]) -> anyhow::Result<Self> {
        let cache = tempfile::tempdir()?;
        let mut child = wrapped(crate::bin("reliefd"))
            .envs(env.iter().map(|(k, v)| (k.as_str(), v.as_str())))
            .env("XDG_CACHE_HOME", cache.path())
            .arg("serve")
            .arg(manifest)
            .args(if extra.contains(&"--listen") { &[][..] } else { &["--listen", "127.0.0.1:0"][..] })
            .args(extra)
            .env("RUST_LOG", std::env::var("RELIEF_TEST_LOG").unwrap_or_else(|_| "info".into()))
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .context("cannot start reliefd (is it built? cargo build --workspace)")?;
        let log = Arc::new(Mutex::new(Vec::new()));
        let stderr = child.stderr.take().context("reliefd has no stderr")?;
        let err_log = Arc::clone(&log);
        let (log_done, log_ended) = mpsc::channel();
        std::thread::Builder::new().name("reliefd-stderr".into()).spawn(move || {
            each_line(stderr, |line| err_log.lock().expect("log lock").push(line));
            let _ = log_done.send(());
        })?;
        let stdout = child.stdout.take().context("reliefd has no stdout")?;
        let (tx, rx) = mpsc::sync_channel(1);
        let printed = Arc::new(Mutex::new(Vec::new()));
        let out_log = Arc::clone(&printed);
        std::thread::Builder::new().name("reliefd-stdout".into()).spawn(move || {
            each_line(stdout, |line| {
                if let Some(addr) = line.strip_prefix("listening on ") {
                    let _ = tx.send(addr.to_owned());
                }
                out_log.lock().expect("log lock").push(line);
            });
        })?;
        match rx.recv_timeout(Duration::from_secs(60)) {
            Ok(addr) => Ok(Self { child, addr, log, log_ended: Mutex::new(log_ended), printed, _cache: cache }),
            Err(_) => {
                let _ = child.kill();
                let _ = child.wait();
                // A daemon that refused its scene closes stdout as it exits,
                // which can be before its error line reaches the log.
                let _ = log_ended.recv_timeout(LOG_END_WAIT);
                bail!("reliefd did not start: {}", log.lock().expect("log lock").join("\n"))
            }
        }
    }

    /// The rest of the first stdout line that starts with `prefix`
    /// (`"metrics: "`, say), waiting up to 5 s for it.
    pub fn printed(&self, prefix: &str) -> Option<String> {
        for _ in 0..100 {
            let lines = self.printed.lock().expect("log lock").clone();
            if let Some(rest) = lines.iter().find_map(|l| l.strip_prefix(prefix)) {
                return Some(rest.to_owned());
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        None
    }

    pub fn url(&self) -> String {
        format!("http://{}", self.addr)
    }

    pub async fn channel(&self) -> anyhow::Result<Channel> {
        // Wide HTTP/2 windows, as the CLI uses: a tile arrives in one flight.
        Ok(Channel::from_shared(self.url())?
            .initial_stream_window_size(8 * 1024 * 1024)
            .initial_connection_window_size(16 * 1024 * 1024)
            .connect()
            .await?)
    }

    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    pub fn is_running(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }

    pub fn log(&self) -> Vec<String> {
        self.log.lock().expect("log lock").clone()
    }

    /// SIGTERM, wait for a clean exit, and return the log. Fails if the
    /// daemon logged a WARN or ERROR line that no `allowed` text explains.
    pub fn stop(mut self, allowed: &[&str]) -> anyhow::Result<Vec<String>> {
        let pid = self.child.id().to_string();
        Command::new("kill").args(["-TERM", &pid]).status()?;
        for _ in 0..100 {
            if let Some(status) = self.child.try_wait()? {
                // Every line it wrote before it exited, not those the reader
                // had reached.
                let _ = self.log_ended.lock().expect("log lock").recv_timeout(LOG_END_WAIT);
                if !status.success() {
                    bail!("reliefd exited with {status}: {}", self.log().join("\n"));
                }
                let log = self.log();
                let unexpected: Vec<&String> = log
                    .iter()
                    .filter(|l| l.contains(" WARN ") || l.contains(" ERROR "))
                    .filter(|l| !allowed.iter().any(|a| l.contains(a)))
                    .collect();
                if !unexpected.is_empty() {
                    bail!("reliefd logged unexpected warnings: {unexpected:#?}");
                }
                return Ok(log);
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        bail!("reliefd did not stop within 5 s of SIGTERM")
    }
}

impl Drop for Reliefd {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Calls `f` with each line `reader` gives, to its end; bytes that are not
/// UTF-8 (a path in another encoding) are replaced, never the end of it.
fn each_line(reader: impl std::io::Read, mut f: impl FnMut(String)) {
    let mut reader = BufReader::new(reader);
    let mut line = Vec::new();
    while reader.read_until(b'\n', &mut line).is_ok_and(|n| n > 0) {
        f(String::from_utf8_lossy(&line).trim_end_matches(['\n', '\r']).to_owned());
        line.clear();
    }
}

/// A command running `program`, under RELIEF_DAEMON_WRAP's command where
/// that is set.
fn wrapped(program: std::path::PathBuf) -> Command {
    let wrap = std::env::var("RELIEF_DAEMON_WRAP").unwrap_or_default();
    let mut words = wrap.split_whitespace();
    match words.next() {
        Some(first) => {
            let mut command = Command::new(first);
            command.args(words).arg(program);
            command
        }
        None => Command::new(program),
    }
}

/// Runs `reliefd check MANIFEST`: (exit code, stderr).
pub fn check(manifest: &Path) -> anyhow::Result<(i32, String)> {
    let cache = tempfile::tempdir()?;
    let out =
        Command::new(crate::bin("reliefd")).env("XDG_CACHE_HOME", cache.path()).arg("check").arg(manifest).output()?;
    Ok((out.status.code().unwrap_or(-1), String::from_utf8_lossy(&out.stderr).into_owned()))
}

/// Runs the `relief` CLI against `daemon`: (exit code, stdout, stderr).
pub fn relief(daemon: &Reliefd, args: &[&str]) -> anyhow::Result<(i32, String, String)> {
    let out = Command::new(crate::bin("relief")).args(["--server", &daemon.url()]).args(args).output()?;
    Ok((
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    ))
}
