//! A real Redis for the tests: Debian's `redis-server` on a private Unix
//! socket in a temporary folder, no persistence, stopped when dropped.

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use anyhow::Context;

pub struct Redis {
    child: Child,
    socket: PathBuf,
    _dir: tempfile::TempDir,
}

impl Redis {
    /// Starts `redis-server` (installed by `scripts/setup.sh`).
    pub fn start() -> anyhow::Result<Self> {
        let dir = tempfile::tempdir()?;
        let socket = dir.path().join("redis.sock");
        let child = Command::new("redis-server")
            .args(["--port", "0", "--save", "", "--appendonly", "no", "--unixsocketperm", "700"])
            .arg("--unixsocket")
            .arg(&socket)
            .arg("--dir")
            .arg(dir.path())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .context("cannot start redis-server (scripts/setup.sh installs Debian's redis-server)")?;
        let redis = Self { child, socket, _dir: dir };
        for _ in 0..200 {
            if redis.socket.exists() {
                return Ok(redis);
            }
            std::thread::sleep(Duration::from_millis(25));
        }
        anyhow::bail!("redis-server did not open {} within 5 s", redis.socket.display())
    }

    /// How many keys match `pattern`, asked through `redis-cli`.
    pub fn count(&self, pattern: &str) -> anyhow::Result<usize> {
        let out = Command::new("redis-cli").arg("-s").arg(&self.socket).args(["--raw", "KEYS", pattern]).output()?;
        anyhow::ensure!(out.status.success(), "redis-cli failed: {}", String::from_utf8_lossy(&out.stderr));
        Ok(String::from_utf8_lossy(&out.stdout).lines().filter(|l| !l.trim().is_empty()).count())
    }

    /// The address reliefd's `[cache] redis` takes.
    pub fn url(&self) -> String {
        format!("unix://{}", self.socket.display())
    }
}

impl Drop for Redis {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
