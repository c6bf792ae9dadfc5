//! The architecture's invariants that a reader cannot see at a glance,
//! checked on the source itself (issue 37): the engine depends on no
//! serving crate, and no two files of a crate import each other in a
//! circle, directly or through others, so that each can be read after the
//! files below it.
//!
//! A file's imports are the paths it names (`crate::a::b`, `super::x`,
//! `self::y`, a child module's `z::`), `use` groups included, outside
//! comments and its `#[cfg(test)]` tail; each resolves to the deepest
//! module file it reaches. A parent module that names its children is
//! fine; a child that names its parent's items makes a circle (move what
//! the children share into a file of its own).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The crates whose files are held to it. (The gdal source's `raster/`
/// is not yet: its files share `raster/mod.rs`'s `Raster` and `Store`, and
/// `header.rs` builds them from the others; see ARCHITECTURE.md.)
const CRATES: [&str; 3] = ["engine/src", "daemon/src", "renderer/src"];

/// Every `.rs` file under `root` by module path (`backing::codec`; the
/// crate root is "").
fn modules(root: &Path) -> BTreeMap<String, PathBuf> {
    let mut found = BTreeMap::new();
    let mut dirs = vec![root.to_path_buf()];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())).flatten() {
            let path = entry.path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                let relative = path.strip_prefix(root).expect("under the root").with_extension("");
                let mut parts: Vec<String> = relative.iter().map(|p| p.to_string_lossy().into_owned()).collect();
                if parts.last().is_some_and(|l| l == "mod" || l == "lib" || l == "main") {
                    parts.pop();
                }
                found.insert(parts.join("::"), path);
            }
        }
    }
    found
}

/// The text that counts: comments out, the `#[cfg(test)]` tail cut.
fn code(text: &str) -> String {
    let text = text.find("#[cfg(test)]").map_or(text, |i| &text[..i]);
    text.lines().map(|l| l.find("//").map_or(l, |i| &l[..i])).collect::<Vec<_>>().join("\n")
}

fn is_ident(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_'
}

/// The paths a path expression at `at` names (after its first `::`),
/// `{a, b::c}` groups expanded: each a list of segments.
fn paths(text: &[char], at: usize) -> Vec<Vec<String>> {
    fn parse(text: &[char], mut i: usize, prefix: Vec<String>, out: &mut Vec<Vec<String>>) -> usize {
        let mut segs = prefix;
        loop {
            while i < text.len() && text[i].is_whitespace() {
                i += 1;
            }
            if i < text.len() && text[i] == '{' {
                i += 1;
                loop {
                    i = parse(text, i, segs.clone(), out);
                    while i < text.len() && text[i].is_whitespace() {
                        i += 1;
                    }
                    match text.get(i) {
                        Some(',') => i += 1,
                        Some('}') => return i + 1,
                        _ => return i,
                    }
                }
            }
            let start = i;
            while i < text.len() && is_ident(text[i]) {
                i += 1;
            }
            if i == start {
                out.push(segs);
                return i;
            }
            segs.push(text[start..i].iter().collect());
            if text.get(i) == Some(&':') && text.get(i + 1) == Some(&':') {
                i += 2;
            } else {
                out.push(segs);
                return i;
            }
        }
    }
    let mut out = Vec::new();
    parse(text, at, Vec::new(), &mut out);
    out
}

/// The module files each file names.
fn imports(files: &BTreeMap<String, PathBuf>) -> BTreeMap<String, BTreeSet<String>> {
    let mut edges = BTreeMap::new();
    for (module, path) in files {
        let text: Vec<char> = code(&std::fs::read_to_string(path).expect("readable")).chars().collect();
        let base: Vec<String> = module.split("::").filter(|s| !s.is_empty()).map(str::to_owned).collect();
        let mut named = BTreeSet::new();
        let mut i = 0;
        while i < text.len() {
            let starts_word = i == 0 || !(is_ident(text[i - 1]) || text[i - 1] == ':');
            if !starts_word || !is_ident(text[i]) {
                i += 1;
                continue;
            }
            let start = i;
            while i < text.len() && is_ident(text[i]) {
                i += 1;
            }
            if text.get(i) != Some(&':') || text.get(i + 1) != Some(&':') {
                continue;
            }
            let word: String = text[start..i].iter().collect();
            let mut anchor = match word.as_str() {
                "crate" => Vec::new(),
                "self" => base.clone(),
                "super" => base[..base.len().saturating_sub(1)].to_vec(),
                child => {
                    let mut m = base.clone();
                    m.push(child.to_owned());
                    if !files.contains_key(&m.join("::")) {
                        continue;
                    }
                    m.pop();
                    i = start;
                    m
                }
            };
            let after = if i == start { i } else { i + 2 };
            for mut path in paths(&text, after) {
                while path.first().is_some_and(|s| s == "super") {
                    path.remove(0);
                    anchor.pop();
                }
                let mut full = anchor.clone();
                full.extend(path);
                let target = (0..=full.len()).rev().map(|k| full[..k].join("::")).find(|m| files.contains_key(m));
                if let Some(target) = target.filter(|t| t != module) {
                    named.insert(target);
                }
            }
            i = after.max(i + 1);
        }
        edges.insert(module.clone(), named);
    }
    edges
}

/// The groups of two or more files that reach each other (Tarjan's
/// strongly connected components).
fn circles(edges: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct Walk<'a> {
        edges: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        out: Vec<Vec<String>>,
    }
    impl<'a> Walk<'a> {
        fn visit(&mut self, v: &'a str) {
            let n = self.index.len();
            self.index.insert(v, n);
            self.low.insert(v, n);
            self.stack.push(v);
            for w in self.edges.get(v).into_iter().flatten() {
                if !self.index.contains_key(w.as_str()) {
                    self.visit(w);
                    let low = self.low[v].min(self.low[w.as_str()]);
                    self.low.insert(v, low);
                } else if self.stack.contains(&w.as_str()) {
                    let low = self.low[v].min(self.index[w.as_str()]);
                    self.low.insert(v, low);
                }
            }
            if self.low[v] == self.index[v] {
                let mut group = Vec::new();
                while let Some(w) = self.stack.pop() {
                    group.push(w.to_owned());
                    if w == v {
                        break;
                    }
                }
                if group.len() > 1 {
                    group.sort();
                    self.out.push(group);
                }
            }
        }
    }
    let mut walk = Walk { edges, index: BTreeMap::new(), low: BTreeMap::new(), stack: Vec::new(), out: Vec::new() };
    for v in edges.keys() {
        if !walk.index.contains_key(v.as_str()) {
            walk.visit(v);
        }
    }
    walk.out
}

#[test]
fn no_two_files_of_a_crate_import_each_other_in_a_circle() {
    let mut found = Vec::new();
    for krate in CRATES {
        let files = modules(&relief_tests::workspace_root().join(krate));
        assert!(files.len() > 5, "{krate}: no sources found");
        let edges = imports(&files);
        for group in circles(&edges) {
            let lines: Vec<String> = group
                .iter()
                .map(|m| {
                    let inside: Vec<&str> = edges[m].iter().filter(|t| group.contains(t)).map(String::as_str).collect();
                    format!("    {} -> {}", if m.is_empty() { "<root>" } else { m }, inside.join(", "))
                })
                .collect();
            found.push(format!("{krate}: {}\n{}", group.join(", "), lines.join("\n")));
        }
    }
    assert!(found.is_empty(), "files that import each other in a circle:\n{}", found.join("\n"));
}

/// The checker itself, on files written for it: a circle through a
/// parent's item is found, `use` groups and `super::` resolve, and a
/// parent naming its children alone is no circle.
#[test]
fn the_checker_finds_a_circle_through_a_group_and_a_parents_item() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let write = |name: &str, text: &str| {
        let path = dir.path().join(name);
        std::fs::create_dir_all(path.parent().expect("a parent")).expect("a folder");
        std::fs::write(path, text).expect("written");
    };
    write("lib.rs", "mod a;\nmod b;\npub use a::Thing;\n");
    write("a/mod.rs", "mod inner;\npub use inner::Thing;\n// crate::b::never (a comment)\n");
    write("a/inner.rs", "pub struct Thing;\n#[cfg(test)]\nmod tests { use crate::b::Other; }\n");
    write("b.rs", "use crate::{a::{Thing}, c};\npub struct Other;\n");
    write("c.rs", "pub struct Unit;\n");
    let files = modules(dir.path());
    let edges = imports(&files);
    assert_eq!(edges["b"], BTreeSet::from(["a".to_owned(), "c".to_owned()]), "{edges:?}");
    assert!(edges["a::inner"].is_empty(), "a test module counts: {edges:?}");
    assert!(edges["a"].contains("a::inner") && !edges["a"].contains("b"), "{edges:?}");
    assert!(circles(&edges).is_empty(), "{edges:?}");
    write("a/inner.rs", "pub struct Thing(crate::c::Unit);\n");
    write("c.rs", "pub struct Unit;\npub fn f() -> super::b::Other { super::b::Other }\n");
    let edges = imports(&modules(dir.path()));
    assert_eq!(circles(&edges), vec![vec!["a".to_owned(), "a::inner".to_owned(), "b".to_owned(), "c".to_owned()]]);
}

/// What serves or draws: none may be among the engine's dependencies.
const SERVING: [&str; 8] =
    ["tonic", "prost", "axum", "hyper", "wgpu", "relief-proto", "relief-renderer", "relief-daemon"];

/// `cargo tree -p relief-engine` (normal dependencies, what the engine is
/// built with) names none of the serving crates.
#[test]
fn the_engine_depends_on_no_transport_renderer_or_proto() {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = std::process::Command::new(cargo)
        .args(["tree", "-p", "relief-engine", "-e", "normal", "--prefix", "none", "--offline"])
        .current_dir(relief_tests::workspace_root())
        .output()
        .expect("cargo runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "cargo tree failed: {}", String::from_utf8_lossy(&out.stderr));
    let crates: BTreeSet<&str> = text.lines().filter_map(|l| l.split_whitespace().next()).collect();
    assert!(crates.contains("relief-engine") && crates.contains("relief-source"), "{text}");
    let found: Vec<&&str> = SERVING.iter().filter(|c| crates.contains(**c)).collect();
    assert!(found.is_empty(), "relief-engine depends on {found:?}:\n{text}");
}
