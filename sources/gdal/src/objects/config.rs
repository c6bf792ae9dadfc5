//! GDAL's settings for objects, from the standard AWS environment and the
//! manifest's `[storage]`, and the rule that keeps secrets out of words.
//!
//! GDAL reads `AWS_ACCESS_KEY_ID`, `AWS_SECRET_ACCESS_KEY`,
//! `AWS_SESSION_TOKEN`, `AWS_REGION`, `AWS_PROFILE` and the `~/.aws` files
//! itself. What GDAL 3.6 does not read is translated here:
//! `AWS_ENDPOINT_URL_S3` or `AWS_ENDPOINT_URL` (the SDKs' names) become
//! GDAL's `AWS_S3_ENDPOINT` with `AWS_HTTPS` from the URL's scheme and
//! path-style addressing (`AWS_VIRTUAL_HOSTING=FALSE`: a custom endpoint
//! is a MinIO, a Ceph, a moto, whose buckets are not host names). With no
//! credentials anywhere, requests go unsigned (a public bucket) rather than
//! to the EC2 metadata service.

use std::path::PathBuf;
use std::sync::{Mutex, PoisonError};

/// The manifest's `[storage]`: overrides of the environment for the
/// scene's objects.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Storage {
    /// The S3 endpoint's URL (`http://minio:9000`), over
    /// `AWS_ENDPOINT_URL_S3` and `AWS_ENDPOINT_URL`.
    pub endpoint: Option<String>,
    /// The region, over `AWS_REGION`.
    pub region: Option<String>,
    /// Requests unsigned (a public bucket), whatever credentials exist.
    pub anonymous: bool,
}

/// The settings applied last (set again only when they change).
static APPLIED: Mutex<Option<(Storage, bool)>> = Mutex::new(None);

use crate::set_option as set;

fn clear(key: &str) {
    let _unknown_option_is_harmless = gdal::config::clear_config_option(key);
}

/// Sets GDAL up for the scene's objects: `reaches_objects` when the scene
/// names any (else GDAL's HTTP stays sent nowhere, as for a scene of local
/// files), with `storage`'s overrides of the environment.
pub fn configure_storage(storage: &Storage, reaches_objects: bool) {
    crate::guard::configure();
    let mut applied = APPLIED.lock().unwrap_or_else(PoisonError::into_inner);
    let wanted = (storage.clone(), reaches_objects);
    if applied.as_ref() == Some(&wanted) {
        return;
    }
    if !reaches_objects {
        crate::guard::block_http();
        *applied = Some(wanted);
        return;
    }
    clear("GDAL_HTTP_PROXY");
    clear("GDAL_HTTPS_PROXY");
    // As COG servers set GDAL: a request per range asked, consecutive ones
    // merged, a bounded cache of what was fetched, patience for a slow
    // store but not for a dead one.
    set("GDAL_HTTP_MERGE_CONSECUTIVE_RANGES", "YES");
    set("GDAL_HTTP_MULTIPLEX", "YES");
    set("CPL_VSIL_CURL_CACHE_SIZE", &(64u64 << 20).to_string());
    set("VSI_CACHE", "TRUE");
    set("VSI_CACHE_SIZE", &(8u64 << 20).to_string());
    set("GDAL_HTTP_TIMEOUT", "30");
    set("GDAL_HTTP_CONNECTTIMEOUT", "5");
    set("GDAL_HTTP_MAX_RETRY", "2");
    set("GDAL_HTTP_RETRY_DELAY", "0.5");
    let env = |k: &str| std::env::var(k).ok().filter(|v| !v.trim().is_empty());
    match storage.endpoint.clone().or_else(|| env("AWS_ENDPOINT_URL_S3")).or_else(|| env("AWS_ENDPOINT_URL")) {
        Some(url) => {
            let (https, host) = match url.split_once("://") {
                Some((scheme, rest)) => (!scheme.eq_ignore_ascii_case("http"), rest),
                None => (true, url.as_str()),
            };
            set("AWS_S3_ENDPOINT", host.trim_end_matches('/'));
            set("AWS_HTTPS", if https { "YES" } else { "NO" });
            set("AWS_VIRTUAL_HOSTING", "FALSE");
        }
        None if env("AWS_S3_ENDPOINT").is_none() => {
            clear("AWS_S3_ENDPOINT");
            clear("AWS_HTTPS");
            clear("AWS_VIRTUAL_HOSTING");
        }
        None => {}
    }
    match &storage.region {
        Some(region) => set("AWS_REGION", region),
        None => clear("AWS_REGION"),
    }
    let credentials = env("AWS_ACCESS_KEY_ID").is_some()
        || env("AWS_PROFILE").is_some()
        || env("AWS_WEB_IDENTITY_TOKEN_FILE").is_some()
        || aws_files().iter().any(|f| f.is_file());
    set("AWS_NO_SIGN_REQUEST", if storage.anonymous || !credentials { "YES" } else { "NO" });
    *applied = Some(wanted);
}

/// The `~/.aws` files GDAL reads credentials from (or where the AWS
/// variables move them).
fn aws_files() -> Vec<PathBuf> {
    let home = std::env::var_os("HOME").map(PathBuf::from).unwrap_or_default();
    let var = |k: &str, default: &str| std::env::var_os(k).map_or_else(|| home.join(default), PathBuf::from);
    vec![var("AWS_SHARED_CREDENTIALS_FILE", ".aws/credentials"), var("AWS_CONFIG_FILE", ".aws/config")]
}

/// `text` without secrets: every URL's query string (a presigned URL's
/// signature) cut, and the values of the AWS secret variables replaced.
pub fn redact(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(at) = rest.find("://") {
        let (head, tail) = rest.split_at(at);
        out.push_str(head);
        let end =
            tail.find(|c: char| c.is_whitespace() || matches!(c, '\'' | '"' | '`' | '<' | '>')).unwrap_or(tail.len());
        let url = &tail[..end];
        out.push_str(relief_source::objects::without_query(url));
        if url.contains(['?', '#']) {
            out.push_str("?…");
        }
        rest = &tail[end..];
    }
    out.push_str(rest);
    for key in ["AWS_SECRET_ACCESS_KEY", "AWS_SESSION_TOKEN"] {
        if let Ok(secret) = std::env::var(key)
            && secret.len() >= 4
        {
            out = out.replace(&secret, "***");
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls_lose_their_queries() {
        assert_eq!(
            redact("HTTP error on https://h.example/d.tif?X-Amz-Signature=abc&X-Amz-Credential=k: 403"),
            "HTTP error on https://h.example/d.tif?… 403"
        );
        assert_eq!(redact("plain words"), "plain words");
        assert_eq!(redact("s3://b/k and http://h/p"), "s3://b/k and http://h/p");
    }
}
