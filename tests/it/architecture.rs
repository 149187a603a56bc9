//! The house has no circles: the import graph of `src/` (one node per file,
//! an edge for every `crate::…`, `super::…` or `self::…` path, and every
//! intra-doc link, that names another file's module) has no cycle, neither
//! between files nor between folders, and the pipeline sits on top: nothing
//! below it (`align/`, `imu/`, `io/`, `map/`, `sim/`, the models) imports it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Module path of a source file (`src/io/mcap/log.rs` → `io::mcap::log`,
/// `src/io/mod.rs` → `io`, `src/lib.rs` → ``).
fn module_of(root: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(root).unwrap().with_extension("");
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib")) {
        parts.pop();
    }
    parts
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The code of a file without its test module, comments, string and char
/// literals (a path inside a message or a comment is not an import), but with
/// the targets of the intra-doc links of its doc comments: rustdoc resolves
/// `[`crate::a::b`]` like a `use`, so a link up the layers is a circle too.
fn code_of(text: &str) -> String {
    let text = match text.find("#[cfg(test)]") {
        Some(i) => &text[..i],
        None => text,
    };
    let c: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < c.len() {
        match c[i] {
            '/' if c.get(i + 1) == Some(&'/') => {
                let start = i;
                while i < c.len() && c[i] != '\n' {
                    i += 1;
                }
                let comment: String = c[start..i].iter().collect();
                if comment.starts_with("///") || comment.starts_with("//!") {
                    for target in doc_link_targets(&comment) {
                        out.push(' ');
                        out.push_str(&target);
                        out.push(' ');
                    }
                }
            }
            '/' if c.get(i + 1) == Some(&'*') => {
                i += 2;
                while i + 1 < c.len() && !(c[i] == '*' && c[i + 1] == '/') {
                    i += 1;
                }
                i += 2;
            }
            'r' if c.get(i + 1).is_some_and(|&x| x == '"' || x == '#')
                && !c
                    .get(i.wrapping_sub(1))
                    .is_some_and(|x| x.is_alphanumeric() || *x == '_') =>
            {
                // r"..." or r#"..."#
                let mut j = i + 1;
                let mut hashes = 0;
                while c.get(j) == Some(&'#') {
                    hashes += 1;
                    j += 1;
                }
                if c.get(j) != Some(&'"') {
                    out.push(c[i]);
                    i += 1;
                    continue;
                }
                j += 1;
                loop {
                    if j >= c.len() {
                        break;
                    }
                    if c[j] == '"' && (0..hashes).all(|k| c.get(j + 1 + k) == Some(&'#')) {
                        j += 1 + hashes;
                        break;
                    }
                    j += 1;
                }
                i = j;
            }
            '"' => {
                i += 1;
                while i < c.len() && c[i] != '"' {
                    if c[i] == '\\' {
                        i += 1;
                    }
                    i += 1;
                }
                i += 1;
            }
            '\'' => {
                // A char literal ('x', '\n', '\u{..}') or a lifetime ('a).
                let close = (i + 2..(i + 12).min(c.len())).find(|&k| c[k] == '\'');
                match close {
                    Some(k) if c[i + 1] == '\\' || k == i + 2 => i = k + 1,
                    _ => {
                        out.push(c[i]);
                        i += 1;
                    }
                }
            }
            ch => {
                out.push(ch);
                i += 1;
            }
        }
    }
    out
}

/// The targets of the intra-doc links of one doc-comment line:
/// ``[`path`]`` and ``[text](path)``.
fn doc_link_targets(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = line;
    while let Some(i) = rest.find("[`") {
        rest = &rest[i + 2..];
        if let Some(j) = rest.find("`]") {
            out.push(rest[..j].to_string());
            rest = &rest[j + 2..];
        }
    }
    let mut rest = line;
    while let Some(i) = rest.find("](") {
        rest = &rest[i + 2..];
        if let Some(j) = rest.find(')') {
            out.push(rest[..j].to_string());
            rest = &rest[j + 1..];
        }
    }
    out
}

/// Every path `crate::a::b…` / `super::…` / `self::…` in `code`, including
/// those inside `use` trees (`use crate::a::{b, c::d}` gives `a::b`, `a::c::d`).
fn paths_in(code: &str) -> Vec<(String, Vec<String>)> {
    let mut out = Vec::new();
    // `use` statements, with their brace trees expanded.
    let mut rest = code;
    while let Some(i) = rest.find("use ") {
        let before = rest[..i].chars().last();
        rest = &rest[i + 4..];
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        let Some(end) = rest.find(';') else { break };
        let stmt: String = rest[..end].split_whitespace().collect();
        expand(&stmt, &mut Vec::new(), &mut out);
        rest = &rest[end..];
    }
    // Paths written inline (`crate::io::text::read_tum(...)`).
    for root in ["crate::", "super::"] {
        let mut from = 0;
        while let Some(i) = code[from..].find(root) {
            let start = from + i;
            let end = code[start..]
                .find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
                .map_or(code.len(), |k| start + k);
            let segs: Vec<String> = code[start..end]
                .split("::")
                .filter(|s| !s.is_empty())
                .map(str::to_string)
                .collect();
            if let Some((head, tail)) = segs.split_first() {
                out.push((head.clone(), tail.to_vec()));
            }
            from = end.max(start + 1);
        }
    }
    out
}

/// Expands one `use` tree (whitespace removed) under `prefix`.
fn expand(tree: &str, prefix: &mut Vec<String>, out: &mut Vec<(String, Vec<String>)>) {
    if let Some(open) = tree.find('{') {
        let head: Vec<String> = tree[..open]
            .split("::")
            .filter(|s| !s.is_empty())
            .map(str::to_string)
            .collect();
        let inner = &tree[open + 1..tree.rfind('}').unwrap_or(tree.len())];
        let mut depth = 0;
        let mut start = 0;
        let mut parts = Vec::new();
        for (k, c) in inner.char_indices() {
            match c {
                '{' => depth += 1,
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    parts.push(&inner[start..k]);
                    start = k + 1;
                }
                _ => {}
            }
        }
        parts.push(&inner[start..]);
        let n = prefix.len();
        prefix.extend(head);
        for p in parts.into_iter().filter(|p| !p.is_empty()) {
            expand(p, prefix, out);
        }
        prefix.truncate(n);
        return;
    }
    let path = tree.split(" as ").next().unwrap_or(tree);
    let mut segs: Vec<String> = prefix.clone();
    segs.extend(
        path.split("::")
            .filter(|s| !s.is_empty())
            .map(|s| s.split("as").next().unwrap_or(s).to_string()),
    );
    if let Some((head, tail)) = segs.split_first() {
        if matches!(head.as_str(), "crate" | "super" | "self") {
            out.push((head.clone(), tail.to_vec()));
        }
    }
}

type Graph = BTreeMap<Vec<String>, BTreeSet<Vec<String>>>;

/// The import graph of the crate's `src/`.
fn graph() -> Graph {
    graph_of(&Path::new(env!("CARGO_MANIFEST_DIR")).join("src"))
}

/// The import graph of the sources under `root`: module → modules it imports.
fn graph_of(root: &Path) -> Graph {
    let mut files = Vec::new();
    rust_files(root, &mut files);
    let modules: BTreeMap<Vec<String>, PathBuf> = files
        .iter()
        .map(|f| (module_of(root, f), f.clone()))
        .collect();
    // The longest prefix of `path` that is a module of its own file.
    let resolve = |path: &[String]| -> Option<Vec<String>> {
        (1..=path.len())
            .rev()
            .map(|k| path[..k].to_vec())
            .find(|p| modules.contains_key(p))
    };
    let mut edges: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> = BTreeMap::new();
    for (module, file) in &modules {
        let is_mod_file = file
            .file_name()
            .is_some_and(|n| n == "mod.rs" || n == "lib.rs");
        let code = code_of(&std::fs::read_to_string(file).unwrap());
        let mut targets = BTreeSet::new();
        for (head, mut tail) in paths_in(&code) {
            // A file's own module is its path; `super` of `a/b.rs` is `a`,
            // `super` of `a/b/mod.rs` is `a` too (the mod file is `a::b`).
            let mut base: Vec<String> = match head.as_str() {
                "crate" => Vec::new(),
                "self" if is_mod_file => module.clone(),
                "self" => module.clone(),
                _ => {
                    let mut b = module.clone();
                    b.pop();
                    b
                }
            };
            while tail.first().is_some_and(|s| s == "super") {
                tail.remove(0);
                base.pop();
            }
            base.extend(tail);
            if let Some(t) = resolve(&base) {
                if &t != module && !t.is_empty() {
                    targets.insert(t);
                }
            }
        }
        edges.insert(module.clone(), targets);
    }
    edges
}

fn name(m: &[String]) -> String {
    if m.is_empty() {
        "lib".into()
    } else {
        m.join("::")
    }
}

/// A cycle of the graph, as module names from its first node back to it.
fn find_cycle(g: &Graph) -> Option<Vec<String>> {
    fn visit(
        v: &Vec<String>,
        g: &Graph,
        state: &mut BTreeMap<Vec<String>, u8>,
        stack: &mut Vec<Vec<String>>,
    ) -> Option<Vec<String>> {
        state.insert(v.clone(), 1);
        stack.push(v.clone());
        for w in g.get(v).into_iter().flatten() {
            match state.get(w).copied().unwrap_or(0) {
                0 => {
                    if let Some(c) = visit(w, g, state, stack) {
                        return Some(c);
                    }
                }
                1 => {
                    let at = stack.iter().position(|x| x == w).unwrap_or(0);
                    let mut cycle: Vec<String> = stack[at..].iter().map(|m| name(m)).collect();
                    cycle.push(name(w));
                    return Some(cycle);
                }
                _ => {}
            }
        }
        stack.pop();
        state.insert(v.clone(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for v in g.keys() {
        if state.get(v).copied().unwrap_or(0) == 0 {
            if let Some(c) = visit(v, g, &mut state, &mut Vec::new()) {
                return Some(c);
            }
        }
    }
    None
}

#[test]
fn a_cycle_in_a_small_tree_is_found() {
    // lib.rs, a.rs (imports b through `crate::`), b/mod.rs (imports a through `super::`).
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path();
    std::fs::write(src.join("lib.rs"), "pub mod a;\npub mod b;\n").unwrap();
    std::fs::write(src.join("a.rs"), "use crate::b::{x::Y, Z};\n").unwrap();
    std::fs::create_dir(src.join("b")).unwrap();
    std::fs::write(
        src.join("b/mod.rs"),
        "// use crate::nothing;\nfn f() { super::a::g(); let s = \"crate::a\"; }\n",
    )
    .unwrap();
    let g = graph_of(src);
    assert_eq!(
        find_cycle(&g),
        Some(vec!["a".to_string(), "b".to_string(), "a".to_string()])
    );
    // Without the back edge there is none.
    std::fs::write(src.join("b/mod.rs"), "fn f() {}\n").unwrap();
    assert_eq!(find_cycle(&graph_of(src)), None);
}

#[test]
fn no_file_imports_itself_through_another() {
    let g = graph();
    if let Some(cycle) = find_cycle(&g) {
        panic!("import cycle: {}", cycle.join(" -> "));
    }
    // The parser finds the imports it should: a `use super::…` tree, a
    // `crate::…` path, and well over a hundred edges in all.
    let m = |p: &[&str]| p.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    assert!(g[&m(&["pipeline", "poses"])].contains(&m(&["align", "trajectories"])));
    assert!(g[&m(&["pipeline", "poses"])].contains(&m(&["pipeline", "options"])));
    assert!(g[&m(&["align", "windowed"])].contains(&m(&["trajectory"])));
    let edges: usize = g.values().map(BTreeSet::len).sum();
    assert!(edges > 150, "{edges} edges");
}

/// The graph of the folders one level down (`io/mcap/reader.rs` and
/// `io/mcap/write.rs` are one node `io::mcap`; `io/log.rs` is `io::log`): a
/// folder is one layer, so no file inside it may be imported by a file that
/// one of its files imports.
fn folder_graph(g: &Graph) -> Graph {
    let unit = |m: &Vec<String>| m[..m.len().min(2)].to_vec();
    let mut out: Graph = BTreeMap::new();
    for (m, targets) in g {
        let entry = out.entry(unit(m)).or_default();
        for t in targets {
            if unit(t) != unit(m) {
                entry.insert(unit(t));
            }
        }
    }
    out
}

#[test]
fn no_folder_imports_itself_through_another() {
    if let Some(cycle) = find_cycle(&folder_graph(&graph())) {
        panic!("import cycle between folders: {}", cycle.join(" -> "));
    }
}

#[test]
fn a_doc_link_up_the_layers_is_an_edge() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path();
    std::fs::write(src.join("lib.rs"), "pub mod a;\npub mod b;\n").unwrap();
    std::fs::write(src.join("a.rs"), "use crate::b::X;\n").unwrap();
    // A plain code span names b's user without linking it: no edge.
    std::fs::write(src.join("b.rs"), "//! Used by `crate::a`.\npub struct X;\n").unwrap();
    assert_eq!(find_cycle(&graph_of(src)), None);
    std::fs::write(
        src.join("b.rs"),
        "//! Used by [`crate::a`].\npub struct X;\n",
    )
    .unwrap();
    assert!(find_cycle(&graph_of(src)).is_some());
    std::fs::write(
        src.join("b.rs"),
        "/// See [the user](super::a::f).\npub struct X;\n",
    )
    .unwrap();
    assert!(find_cycle(&graph_of(src)).is_some());
}

#[test]
fn nothing_below_the_pipeline_imports_it() {
    let g = graph();
    for (m, targets) in &g {
        let top = m.first().map(String::as_str).unwrap_or("");
        if matches!(top, "pipeline" | "cli" | "python" | "") {
            continue;
        }
        for t in targets {
            assert_ne!(
                t.first().map(String::as_str),
                Some("pipeline"),
                "{} imports {}",
                name(m),
                name(t)
            );
        }
    }
}

#[test]
fn the_readme_module_table_matches_the_tree() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let start = readme.find("## What is inside").expect("a module table");
    let table: Vec<&str> = readme[start..]
        .lines()
        .skip(1)
        .skip_while(|l| !l.starts_with('|'))
        .take_while(|l| l.starts_with('|'))
        .collect();
    // Every `src/...` path the table names exists.
    let mut named = BTreeSet::new();
    for row in &table {
        let first = row.split('|').nth(1).unwrap_or("");
        for part in first.split('`').skip(1).step_by(2) {
            assert!(
                root.join(part).exists(),
                "README names {part}, which is not in the tree"
            );
            named.insert(part.trim_end_matches('/').to_string());
        }
    }
    // Every folder and file directly under src/ (but lib.rs) is in the table.
    for e in std::fs::read_dir(root.join("src")).unwrap() {
        let name = e.unwrap().file_name().to_string_lossy().into_owned();
        if name == "lib.rs" {
            continue;
        }
        let path = format!("src/{name}");
        assert!(named.contains(&path), "README's module table lacks {path}");
    }
}
