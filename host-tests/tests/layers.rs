//! The workspace's import structure, read from the sources: no import
//! circle between the files of the core or the simulator, and the core's
//! layers (docs/architecture.md) imported only downwards, so that a law
//! and an estimator never import each other (both read the heading
//! estimate from `geometry`, below them).
//!
//! An import is a `use` path or a path written in the code that starts at
//! `crate::` or `super::`; comments, doc comments and test modules are not
//! read. Each path is resolved to the deepest module file it names.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The core's layers, bottom first: a module may import from its own
/// layer's other modules only where no circle results, and from the layers
/// below it.
const CORE_LAYERS: &[&[&str]] = &[
    &["math", "plausible", "builds", "fuzzing"],
    &["geometry"],
    &["odometry", "reference"],
    &["devices", "drive", "filters"],
    &["estimation", "control"],
    &["pilot"],
];

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Every `.rs` file under `dir` but test modules (`tests.rs`,
/// `*_tests.rs`), as module paths (`["estimation", "fusion"]` for
/// `estimation/fusion/mod.rs`) with their text.
fn modules(src: &Path) -> BTreeMap<Vec<String>, String> {
    let mut out = BTreeMap::new();
    let mut stack = vec![src.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
                continue;
            }
            let name = path.file_stem().unwrap().to_str().unwrap().to_owned();
            if path.extension().is_none_or(|e| e != "rs")
                || name == "tests"
                || name.ends_with("_tests")
            {
                continue;
            }
            let rel = path.strip_prefix(src).unwrap();
            let mut module: Vec<String> = rel
                .parent()
                .unwrap()
                .components()
                .map(|c| c.as_os_str().to_str().unwrap().to_owned())
                .collect();
            if path.parent() != Some(src) && matches!(name.as_str(), "lib" | "main") {
                // A binary's own root (src/bin/…): not part of the crate's tree.
                continue;
            }
            if !matches!(name.as_str(), "mod" | "lib" | "main") {
                module.push(name);
            }
            out.insert(module, code_of(&std::fs::read_to_string(&path).unwrap()));
        }
    }
    out
}

/// The text without comments and without a trailing `#[cfg(test)] mod
/// tests { … }`.
fn code_of(text: &str) -> String {
    let text = match text.find("#[cfg(test)]\nmod tests {") {
        Some(at) => &text[..at],
        None => text,
    };
    text.lines()
        .map(|line| match line.find("//") {
            Some(at) => &line[..at],
            None => line,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Expands a `use` tree (`a::{b, c::{d, e}}`) into its paths.
fn expand(tree: &str) -> Vec<String> {
    let tree = tree.trim();
    let Some(open) = tree.find('{') else {
        return vec![tree.split(" as ").next().unwrap().trim().to_owned()];
    };
    let prefix = &tree[..open];
    // A `use ` that is not an import (in a string, say) has no closing brace.
    let Some(close) = tree.rfind('}').filter(|&close| close > open) else {
        return Vec::new();
    };
    let inner = &tree[open + 1..close];
    let mut parts = Vec::new();
    let (mut depth, mut start) = (0, 0);
    for (i, ch) in inner.char_indices() {
        match ch {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                parts.push(&inner[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    parts.push(&inner[start..]);
    parts
        .into_iter()
        .filter(|p| !p.trim().is_empty())
        .flat_map(expand)
        .map(|p| format!("{prefix}{p}"))
        .collect()
}

/// The module paths `code` (of module `here`) imports: `use` trees and
/// paths in the code, from `crate::` or `super::`.
fn imports(here: &[String], code: &str) -> BTreeSet<Vec<String>> {
    let mut paths = Vec::new();
    let mut rest = code;
    while let Some(at) = rest.find("use ") {
        let before = rest[..at].chars().last();
        rest = &rest[at + 4..];
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        let end = rest.find(';').unwrap_or(rest.len());
        paths.extend(expand(&rest[..end]));
        rest = &rest[end..];
    }
    for word in code.split(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':')) {
        if word.starts_with("crate::") || word.starts_with("super::") {
            paths.push(word.to_owned());
        }
    }
    let mut out = BTreeSet::new();
    for path in paths {
        let mut segments: Vec<&str> = path.split("::").filter(|s| !s.is_empty()).collect();
        let mut base: Vec<String> = match segments.first() {
            Some(&"crate") => Vec::new(),
            Some(&"super") => {
                // The parent module.
                let mut b = here.to_vec();
                b.pop();
                b
            }
            _ => continue,
        };
        segments.remove(0);
        while segments.first() == Some(&"super") {
            base.pop();
            segments.remove(0);
        }
        base.extend(segments.iter().map(|s| (*s).to_owned()));
        out.insert(base);
    }
    out
}

/// The import graph between the modules of `src` (each import resolved to
/// the deepest module it names; a module's imports of itself and of its own
/// submodules are left out).
fn graph(src: &Path) -> BTreeMap<Vec<String>, BTreeSet<Vec<String>>> {
    let modules = modules(src);
    let mut edges = BTreeMap::new();
    for (module, code) in &modules {
        let mut to = BTreeSet::new();
        for mut path in imports(module, code) {
            while !path.is_empty() && !modules.contains_key(&path) {
                path.pop();
            }
            if !path.is_empty() && !path.starts_with(module) && !module.starts_with(&path) {
                to.insert(path);
            }
        }
        edges.insert(module.clone(), to);
    }
    edges
}

/// Every circle of the graph, each as the modules on it.
fn circles(edges: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>) -> Vec<Vec<String>> {
    // Tarjan's strongly connected components.
    struct State<'a> {
        edges: &'a BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
        index: BTreeMap<&'a Vec<String>, usize>,
        low: BTreeMap<&'a Vec<String>, usize>,
        stack: Vec<&'a Vec<String>>,
        on_stack: BTreeSet<&'a Vec<String>>,
        found: Vec<Vec<String>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a Vec<String>) {
        let n = s.index.len();
        s.index.insert(v, n);
        s.low.insert(v, n);
        s.stack.push(v);
        s.on_stack.insert(v);
        for w in &s.edges[v] {
            let Some((w, _)) = s.edges.get_key_value(w) else {
                continue;
            };
            if !s.index.contains_key(w) {
                visit(s, w);
                let low = s.low[v].min(s.low[w]);
                s.low.insert(v, low);
            } else if s.on_stack.contains(w) {
                let low = s.low[v].min(s.index[w]);
                s.low.insert(v, low);
            }
        }
        if s.low[v] == s.index[v] {
            let mut component = Vec::new();
            while let Some(w) = s.stack.pop() {
                s.on_stack.remove(w);
                component.push(w.join("::"));
                if w == v {
                    break;
                }
            }
            if component.len() > 1 {
                s.found.push(component);
            }
        }
    }
    let mut s = State {
        edges,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        found: Vec::new(),
    };
    for v in edges.keys() {
        if !s.index.contains_key(v) {
            visit(&mut s, v);
        }
    }
    s.found
}

#[test]
fn no_import_circle_in_the_workspace() {
    for src in [
        "core/src",
        "firmware-sim/src",
        "firmware/link/src",
        "papers/src",
        "firmware/src",
        "xtask/src",
        "host-tests/src",
    ] {
        let edges = graph(&root().join(src));
        assert!(edges.len() > 3, "{src}: {} modules read", edges.len());
        assert_eq!(circles(&edges), Vec::<Vec<String>>::new(), "{src}");
    }
}

#[test]
fn the_cores_layers_import_only_downwards() {
    let rank = |module: &str| {
        CORE_LAYERS
            .iter()
            .position(|layer| layer.contains(&module))
            .unwrap_or_else(|| panic!("core module `{module}` is in no layer of CORE_LAYERS"))
    };
    let edges = graph(&root().join("core/src"));
    let mut wrong = Vec::new();
    for (from, to) in &edges {
        let Some(top) = from.first() else { continue };
        for target in to {
            let target_top = &target[0];
            if target_top != top && rank(target_top) >= rank(top) {
                wrong.push(format!("{} imports {}", from.join("::"), target.join("::")));
            }
        }
    }
    assert_eq!(wrong, Vec::<String>::new());
}

/// The check sees a circle and an upward import where there is one.
#[test]
fn the_check_sees_a_circle() {
    let module = |p: &str| p.split("::").map(str::to_owned).collect::<Vec<_>>();
    let mut edges = BTreeMap::new();
    edges.insert(module("a"), BTreeSet::from([module("b")]));
    edges.insert(module("b"), BTreeSet::from([module("c")]));
    edges.insert(module("c"), BTreeSet::from([module("a")]));
    edges.insert(module("d"), BTreeSet::from([module("a")]));
    assert_eq!(circles(&edges).len(), 1);
    let code = "use crate::{geometry::HeadingEstimate, estimation::{Estimator, fusion::X}};\n\
                let x = super::super::odometry::Step::new();";
    let found = imports(&module("control::saturated"), code);
    assert!(found.contains(&module("estimation::fusion::X")));
    assert!(found.contains(&module("geometry::HeadingEstimate")));
    assert!(found.contains(&module("odometry::Step::new")));
}
