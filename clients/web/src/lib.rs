//! The browser viewer's assets, embedded in reliefd.
//!
//! `index.html`, `viewer.js` (the entry module), the ES modules it imports
//! (`js/*.js`), `viewer.css` and `favicon.svg` are hand-written files beside
//! this crate, taken in whole with `include_str!`: no node, npm or bundler is
//! needed to build or run the viewer (the browser loads the modules itself,
//! each served as JavaScript), and the page fetches nothing from outside the
//! daemon that serves it. The page talks to reliefd's HTTP API
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
    Asset { path: "/viewer.js", content_type: JS, body: include_str!("../viewer.js") },
    Asset { path: "/viewer.css", content_type: "text/css; charset=utf-8", body: include_str!("../viewer.css") },
    Asset { path: "/favicon.svg", content_type: "image/svg+xml", body: include_str!("../favicon.svg") },
    Asset { path: "/js/util.js", content_type: JS, body: include_str!("../js/util.js") },
    Asset { path: "/js/hooks.js", content_type: JS, body: include_str!("../js/hooks.js") },
    Asset { path: "/js/stream.js", content_type: JS, body: include_str!("../js/stream.js") },
    Asset { path: "/js/panel.js", content_type: JS, body: include_str!("../js/panel.js") },
    Asset { path: "/js/camera.js", content_type: JS, body: include_str!("../js/camera.js") },
    Asset { path: "/js/picking.js", content_type: JS, body: include_str!("../js/picking.js") },
    Asset { path: "/js/dirty.js", content_type: JS, body: include_str!("../js/dirty.js") },
    // Not the viewer's: the helper that keeps CesiumJS and MapLibre GL JS
    // views of the standard tiles (/tiles/) live, for pages of their own.
    Asset { path: "/js/relief-tiles.js", content_type: JS, body: include_str!("../js/relief-tiles.js") },
];

/// Modules must be served as JavaScript: a browser refuses a module of any
/// other type.
const JS: &str = "text/javascript; charset=utf-8";

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
    fn every_module_imported_is_an_asset_served_as_javascript() {
        let is_js = |a: &&Asset| std::path::Path::new(a.path).extension().is_some_and(|e| e.eq_ignore_ascii_case("js"));
        for module in ASSETS.iter().filter(is_js) {
            assert_eq!(module.content_type, JS, "{}", module.path);
            for line in module.body.lines().filter(|l| l.starts_with("import ")) {
                let from = line.rsplit(['"']).nth(1).expect("an import names its module in double quotes");
                let dir = module.path.rsplit_once('/').map_or("", |(d, _)| d);
                let path = match from.strip_prefix("./") {
                    Some(rest) => format!("{dir}/{rest}"),
                    None => panic!("{}: import '{from}' is not relative to the module", module.path),
                };
                assert!(
                    asset(&path).is_some_and(|a| a.content_type == JS),
                    "{} imports {path}, not served",
                    module.path
                );
            }
        }
    }

    #[test]
    fn assets_fetch_nothing_from_outside_the_daemon() {
        for asset in ASSETS {
            // The SVG namespace is a name, never fetched.
            let body = asset.body.replace("xmlns=\"http://www.w3.org/2000/svg\"", "");
            assert!(
                !body.contains("://"),
                "{} names an absolute URL; the viewer must load everything from reliefd",
                asset.path
            );
        }
    }
}
