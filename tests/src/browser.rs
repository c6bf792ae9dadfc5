//! A real headless Chromium (Debian's `chromium`), driven over the
//! DevTools protocol through a WebSocket (tokio-tungstenite): open a page,
//! evaluate JavaScript, move and press the mouse, take screenshots. Page
//! exceptions and console errors are collected so a test can fail on them.

use std::collections::HashMap;
use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::{Context, bail};
use futures_util::{SinkExt, StreamExt};
use serde_json::{Value, json};
use tokio::sync::{mpsc, oneshot};
use tokio_tungstenite::tungstenite::Message;

type Pending = Arc<Mutex<HashMap<u64, oneshot::Sender<Value>>>>;

/// True when Chromium is here; else a note on stderr, and the test skips.
pub fn available() -> bool {
    let found = chromium_path().is_some();
    if !found {
        eprintln!("SKIPPED: no chromium (scripts/setup.sh installs it; CI has it)");
    }
    found
}

/// Flags that keep Chromium off every network but loopback: each other
/// address goes to a proxy on the discard port, which refuses it (loopback
/// bypasses a proxy by default), and no host name resolves.
pub const LOOPBACK_ONLY: &[&str] =
    &["--proxy-server=127.0.0.1:9", "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE localhost, EXCLUDE 127.0.0.1"];

/// Where Debian puts Chromium; `RELIEF_CHROMIUM` overrides it.
pub fn chromium_path() -> Option<PathBuf> {
    if let Ok(p) = std::env::var("RELIEF_CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    ["/usr/bin/chromium", "/usr/bin/chromium-browser"].into_iter().map(PathBuf::from).find(|p| p.exists())
}

/// The Chromium process, killed when its last page goes.
struct Process {
    child: Child,
    _profile: tempfile::TempDir,
}

impl Drop for Process {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// One page (tab) of a headless Chromium; `tab` opens another in the same
/// browser, sharing its connections to a host as a person's tabs do.
pub struct Browser {
    process: Arc<Process>,
    out: mpsc::Sender<String>,
    pending: Pending,
    next_id: Arc<std::sync::atomic::AtomicU64>,
    session: String,
    size: (u32, u32),
    /// Exceptions thrown by the pages and console.error lines.
    pub errors: Arc<Mutex<Vec<String>>>,
}

impl Browser {
    /// Starts Chromium headless with a `width` x `height` window and one
    /// blank page attached.
    pub async fn start(width: u32, height: u32) -> anyhow::Result<Self> {
        Self::start_with(width, height, &[]).await
    }

    /// `start` with more command-line `flags` (`LOOPBACK_ONLY`, say).
    pub async fn start_with(width: u32, height: u32, flags: &[&str]) -> anyhow::Result<Self> {
        let path = chromium_path().context("no chromium: apt-get install chromium (scripts/setup.sh does)")?;
        let profile = tempfile::tempdir()?;
        let mut child = Command::new(&path)
            .args([
                "--headless=new",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-dev-shm-usage",
                "--no-first-run",
                "--no-default-browser-check",
                "--disable-extensions",
                "--disable-background-networking",
                "--remote-debugging-address=127.0.0.1",
                "--remote-debugging-port=0",
                &format!("--window-size={width},{height}"),
            ])
            .args(flags)
            .arg(format!("--user-data-dir={}", profile.path().display()))
            .arg("about:blank")
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .with_context(|| format!("cannot start {}", path.display()))?;
        let stderr = child.stderr.take().context("chromium has no stderr")?;
        let (tx, rx) = std::sync::mpsc::sync_channel(1);
        std::thread::Builder::new().name("chromium-stderr".into()).spawn(move || {
            let mut sent = false;
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                if !sent && let Some(url) = line.split_whitespace().find(|w| w.starts_with("ws://")) {
                    let _ = tx.send(url.to_owned());
                    sent = true;
                }
            }
        })?;
        let Ok(url) = rx.recv_timeout(Duration::from_secs(30)) else {
            let _ = child.kill();
            bail!("chromium did not say where its DevTools listen within 30 s");
        };
        let (socket, _) = tokio_tungstenite::connect_async(url.as_str()).await.context("cannot reach DevTools")?;
        let (mut sink, mut source) = socket.split();
        let (out, mut outgoing) = mpsc::channel::<String>(64);
        tokio::spawn(async move {
            while let Some(text) = outgoing.recv().await {
                if sink.send(Message::text(text)).await.is_err() {
                    break;
                }
            }
        });
        let pending: Pending = Arc::default();
        let errors = Arc::new(Mutex::new(Vec::new()));
        let (p, e) = (Arc::clone(&pending), Arc::clone(&errors));
        tokio::spawn(async move {
            while let Some(Ok(message)) = source.next().await {
                let Ok(text) = message.into_text() else { continue };
                let Ok(v) = serde_json::from_str::<Value>(text.as_str()) else { continue };
                if let Some(id) = v.get("id").and_then(Value::as_u64) {
                    if let Some(waiter) = p.lock().expect("lock").remove(&id) {
                        let _ = waiter.send(v);
                    }
                    continue;
                }
                match v["method"].as_str() {
                    Some("Runtime.exceptionThrown") => {
                        let d = &v["params"]["exceptionDetails"];
                        e.lock()
                            .expect("lock")
                            .push(format!("exception: {} {}", d["text"], d["exception"]["description"]));
                    }
                    Some("Runtime.consoleAPICalled") if v["params"]["type"] == "error" => {
                        e.lock().expect("lock").push(format!("console.error: {}", v["params"]["args"]));
                    }
                    _ => {}
                }
            }
        });
        let browser = Self {
            process: Arc::new(Process { child, _profile: profile }),
            out,
            pending,
            next_id: Arc::new(std::sync::atomic::AtomicU64::new(1)),
            session: String::new(),
            size: (width, height),
            errors,
        };
        browser.tab().await
    }

    /// Another page in the same browser, blank, of the same size, behind
    /// this one.
    pub async fn tab(&self) -> anyhow::Result<Self> {
        self.page(false).await
    }

    /// Another page in the same browser in a window of its own: shown
    /// beside the others, not behind them.
    pub async fn window(&self) -> anyhow::Result<Self> {
        self.page(true).await
    }

    async fn page(&self, new_window: bool) -> anyhow::Result<Self> {
        let mut page = Self {
            process: Arc::clone(&self.process),
            out: self.out.clone(),
            pending: Arc::clone(&self.pending),
            next_id: Arc::clone(&self.next_id),
            session: String::new(),
            size: self.size,
            errors: Arc::clone(&self.errors),
        };
        let target =
            page.call("Target.createTarget", json!({ "url": "about:blank", "newWindow": new_window }), false).await?;
        let target_id = target["targetId"].as_str().context("no target id")?.to_owned();
        let attached =
            page.call("Target.attachToTarget", json!({ "targetId": target_id, "flatten": true }), false).await?;
        page.session = attached["sessionId"].as_str().context("no session id")?.to_owned();
        page.send("Page.enable", json!({})).await?;
        page.send("Runtime.enable", json!({})).await?;
        let (width, height) = page.size;
        page.send(
            "Emulation.setDeviceMetricsOverride",
            json!({ "width": width, "height": height, "deviceScaleFactor": 1, "mobile": false }),
        )
        .await?;
        Ok(page)
    }

    /// Brings this page to the front (the others are hidden behind it).
    pub async fn bring_to_front(&self) -> anyhow::Result<()> {
        self.send("Page.bringToFront", json!({})).await?;
        Ok(())
    }

    /// Goes back in the page's history (as the Back button does).
    pub async fn back(&self) -> anyhow::Result<()> {
        let history = self.send("Page.getNavigationHistory", json!({})).await?;
        let index = history["currentIndex"].as_i64().context("no history index")?;
        let entry = &history["entries"][usize::try_from(index - 1).context("no page to go back to")?];
        self.send("Page.navigateToHistoryEntry", json!({ "entryId": entry["id"] })).await?;
        Ok(())
    }

    async fn call(&self, method: &str, params: Value, in_session: bool) -> anyhow::Result<Value> {
        let id = self.next_id.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let mut message = json!({ "id": id, "method": method, "params": params });
        if in_session {
            message["sessionId"] = json!(self.session);
        }
        let (tx, rx) = oneshot::channel();
        self.pending.lock().expect("lock").insert(id, tx);
        self.out.send(message.to_string()).await.context("the DevTools connection is closed")?;
        let answer = tokio::time::timeout(Duration::from_secs(60), rx)
            .await
            .with_context(|| format!("{method}: no answer within 60 s"))?
            .context("the DevTools connection is closed")?;
        if let Some(error) = answer.get("error") {
            bail!("{method}: {error}");
        }
        Ok(answer["result"].clone())
    }

    /// A DevTools command on the page.
    pub async fn send(&self, method: &str, params: Value) -> anyhow::Result<Value> {
        self.call(method, params, true).await
    }

    /// Downloads the page starts land in `dir`.
    pub async fn allow_downloads(&self, dir: &std::path::Path) -> anyhow::Result<()> {
        self.call(
            "Browser.setDownloadBehavior",
            json!({ "behavior": "allow", "downloadPath": dir.display().to_string() }),
            false,
        )
        .await?;
        Ok(())
    }

    pub async fn navigate(&self, url: &str) -> anyhow::Result<()> {
        self.send("Page.navigate", json!({ "url": url })).await?;
        Ok(())
    }

    /// Evaluates `expression` in the page (awaiting a promise) and returns
    /// its value as JSON; a thrown exception is an error.
    pub async fn eval(&self, expression: &str) -> anyhow::Result<Value> {
        let r = self
            .send("Runtime.evaluate", json!({ "expression": expression, "awaitPromise": true, "returnByValue": true }))
            .await?;
        if let Some(e) = r.get("exceptionDetails") {
            bail!("{expression}: {}", e["exception"]["description"].as_str().unwrap_or("exception"));
        }
        Ok(r["result"]["value"].clone())
    }

    /// Evaluates `expression` until it is true, or fails after `timeout`.
    pub async fn wait_for(&self, expression: &str, timeout: Duration) -> anyhow::Result<()> {
        let deadline = tokio::time::Instant::now() + timeout;
        loop {
            if self.eval(expression).await.ok().and_then(|v| v.as_bool()) == Some(true) {
                return Ok(());
            }
            if tokio::time::Instant::now() > deadline {
                bail!("not true within {timeout:?}: {expression}");
            }
            tokio::time::sleep(Duration::from_millis(25)).await;
        }
    }

    /// A mouse event at (x, y) CSS pixels: `kind` is mousePressed,
    /// mouseMoved or mouseReleased.
    pub async fn mouse(&self, kind: &str, x: f64, y: f64, button: &str) -> anyhow::Result<()> {
        let buttons = i32::from(kind != "mouseReleased" && button != "none");
        self.send(
            "Input.dispatchMouseEvent",
            json!({ "type": kind, "x": x, "y": y, "button": button, "buttons": buttons, "clickCount": 1 }),
        )
        .await?;
        Ok(())
    }

    /// A wheel turn at (x, y): `delta_y` pixels, 100 a notch, negative
    /// away from the user (zoom in).
    pub async fn wheel(&self, x: f64, y: f64, delta_y: f64) -> anyhow::Result<()> {
        self.send(
            "Input.dispatchMouseEvent",
            json!({ "type": "mouseWheel", "x": x, "y": y, "deltaX": 0, "deltaY": delta_y }),
        )
        .await?;
        Ok(())
    }

    /// A left-button drag from `from` to `to` in `steps` moves.
    pub async fn drag(&self, from: (f64, f64), to: (f64, f64), steps: u32) -> anyhow::Result<()> {
        self.mouse("mouseMoved", from.0, from.1, "none").await?;
        self.mouse("mousePressed", from.0, from.1, "left").await?;
        for i in 1..=steps {
            let t = f64::from(i) / f64::from(steps);
            self.mouse("mouseMoved", from.0 + (to.0 - from.0) * t, from.1 + (to.1 - from.1) * t, "left").await?;
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        self.mouse("mouseReleased", to.0, to.1, "left").await
    }

    /// A PNG of the page as shown.
    pub async fn screenshot(&self) -> anyhow::Result<Vec<u8>> {
        use base64::Engine as _;
        let r = self.send("Page.captureScreenshot", json!({ "format": "png" })).await?;
        Ok(base64::engine::general_purpose::STANDARD.decode(r["data"].as_str().unwrap_or_default())?)
    }

    pub fn errors(&self) -> Vec<String> {
        self.errors.lock().expect("lock").clone()
    }
}
