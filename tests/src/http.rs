//! A plain HTTP client for reliefd's HTTP transport (ureq, blocking: call
//! it from `spawn_blocking` in async tests), and a reader of Server-Sent
//! Events.

use std::io::{BufRead, BufReader, Read};

use anyhow::Context;

pub struct Reply {
    pub status: u16,
    pub content_type: String,
    pub headers: Vec<(String, String)>,
    pub body: Vec<u8>,
}

impl Reply {
    pub fn json(&self) -> anyhow::Result<serde_json::Value> {
        serde_json::from_slice(&self.body)
            .with_context(|| format!("not JSON ({}): {}", self.status, String::from_utf8_lossy(&self.body)))
    }

    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers.iter().find(|(n, _)| n.eq_ignore_ascii_case(name)).map(|(_, v)| v.as_str())
    }
}

fn agent() -> ureq::Agent {
    ureq::Agent::config_builder().http_status_as_error(false).build().into()
}

/// `method` `url` with an optional JSON body; any status is an answer.
pub fn request(method: &str, url: &str, body: Option<&str>) -> anyhow::Result<Reply> {
    request_with(method, url, body, &[])
}

/// `request` with extra headers (`authorization`, say).
pub fn request_with(method: &str, url: &str, body: Option<&str>, headers: &[(&str, &str)]) -> anyhow::Result<Reply> {
    let agent = agent();
    let with = |mut r: ureq::RequestBuilder<ureq::typestate::WithoutBody>| {
        for (n, v) in headers {
            r = r.header(*n, *v);
        }
        r
    };
    let with_body = |mut r: ureq::RequestBuilder<ureq::typestate::WithBody>| {
        for (n, v) in headers {
            r = r.header(*n, *v);
        }
        r.content_type("application/json").send(body.unwrap_or(""))
    };
    let response = match method {
        "GET" => with(agent.get(url)).call(),
        "DELETE" => with(agent.delete(url)).call(),
        "OPTIONS" => with(agent.options(url)).call(),
        "POST" => with_body(agent.post(url)),
        "PUT" => with_body(agent.put(url)),
        "PATCH" => with_body(agent.patch(url)),
        m => anyhow::bail!("no such method in this client: {m}"),
    }
    .with_context(|| format!("{method} {url}"))?;
    let status = response.status().as_u16();
    let headers = response
        .headers()
        .iter()
        .map(|(n, v)| (n.to_string(), v.to_str().unwrap_or_default().to_owned()))
        .collect::<Vec<_>>();
    let content_type = headers.iter().find(|(n, _)| n == "content-type").map(|(_, v)| v.clone()).unwrap_or_default();
    let body = response.into_body().with_config().limit(256 << 20).read_to_vec()?;
    Ok(Reply { status, content_type, headers, body })
}

pub fn get(url: &str) -> anyhow::Result<Reply> {
    request("GET", url, None)
}

/// Server-Sent Events from a GET, read one event at a time. Dropping it
/// closes the connection.
pub struct Events {
    pub status: u16,
    lines: BufReader<Box<dyn Read + Send>>,
}

impl Events {
    pub fn open(url: &str) -> anyhow::Result<Self> {
        let response = agent().get(url).call().with_context(|| format!("GET {url}"))?;
        let status = response.status().as_u16();
        let reader: Box<dyn Read + Send> = Box::new(response.into_body().into_reader());
        Ok(Self { status, lines: BufReader::new(reader) })
    }

    /// The next event's name and data; None when the stream ends.
    pub fn next_event(&mut self) -> anyhow::Result<Option<(String, String)>> {
        let (mut name, mut data) = (String::from("message"), String::new());
        let mut seen = false;
        loop {
            let mut line = String::new();
            if self.lines.read_line(&mut line)? == 0 {
                return Ok(None);
            }
            let line = line.trim_end_matches(['\r', '\n']);
            if line.is_empty() {
                if seen {
                    return Ok(Some((name, data)));
                }
                continue;
            }
            if let Some(v) = line.strip_prefix("event:") {
                v.trim().clone_into(&mut name);
                seen = true;
            } else if let Some(v) = line.strip_prefix("data:") {
                if !data.is_empty() {
                    data.push('\n');
                }
                data.push_str(v.strip_prefix(' ').unwrap_or(v));
                seen = true;
            }
        }
    }
}
