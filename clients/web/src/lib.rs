//! The browser viewer's assets, embedded in reliefd.
//!
//! `index.html`, `viewer.js` and `viewer.css` are hand-written files beside
//! this crate, taken in whole with `include_str!`: no node, npm or bundler is
//! needed to build or run the viewer, and the page fetches nothing from
//! outside the daemon that serves it. The page talks to reliefd's HTTP API
//! (`/api/...`, the proto3 JSON mapping of relief.v1) on the same origin.
//!
//! This crate owns the bytes and their content types only; serving them is
//! the daemon's job. It depends on nothing.

/// One file of the viewer, as the daemon serves it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Asset {
    /// The URL path it answers, from the root (`/`, `/viewer.js`).
    pub path: &'static str,
    /// The `Content-Type` header to send with it.
    pub content_type: &'static str,
    pub body: &'static str,
}

/// Every asset of the viewer; `/` is the page.
pub const ASSETS: &[Asset] = &[
    Asset { path: "/", content_type: "text/html; charset=utf-8", body: include_str!("../index.html") },
    Asset { path: "/viewer.js", content_type: "text/javascript; charset=utf-8", body: include_str!("../viewer.js") },
    Asset { path: "/viewer.css", content_type: "text/css; charset=utf-8", body: include_str!("../viewer.css") },
];

/// The asset served at `path` (`/index.html` is the page too), if any.
pub fn asset(path: &str) -> Option<&'static Asset> {
    let path = if path == "/index.html" { "/" } else { path };
    ASSETS.iter().find(|asset| asset.path == path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_asset_has_a_body_and_a_content_type() {
        for asset in ASSETS {
            assert!(!asset.body.trim().is_empty(), "{} is empty", asset.path);
            assert!(!asset.content_type.is_empty(), "{} has no content type", asset.path);
            assert!(asset.path.starts_with('/'), "{} is not rooted", asset.path);
        }
    }

    #[test]
    fn the_page_loads_the_script_and_the_stylesheet() {
        let page = asset("/").expect("the page is an asset").body;
        assert!(page.contains("viewer.js"), "index.html does not load viewer.js");
        assert!(page.contains("viewer.css"), "index.html does not load viewer.css");
        assert!(asset("/viewer.js").is_some());
        assert!(asset("/viewer.css").is_some());
    }

    #[test]
    fn index_html_is_the_page_and_unknown_paths_are_none() {
        assert_eq!(asset("/index.html"), asset("/"));
        assert_eq!(asset("/nope.js"), None);
        assert_eq!(asset("viewer.js"), None);
    }

    #[test]
    fn assets_fetch_nothing_from_outside_the_daemon() {
        for asset in ASSETS {
            assert!(
                !asset.body.contains("://"),
                "{} names an absolute URL; the viewer must load everything from reliefd",
                asset.path
            );
        }
    }
}
