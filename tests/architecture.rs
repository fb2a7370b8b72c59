//! The layout of `src/` follows the data flow of a render, and this test
//! keeps it so: every module may use only modules of its own layer or of
//! earlier layers, and no two modules use each other, directly or through
//! others.
//!
//! The layers are stated once, in [`LAYERS`]; the README, `src/lib.rs` and
//! `docs/architecture.md` repeat them in one sentence ([`layer_sentence`]),
//! which this test checks word for word. `error` (the library's `Error`)
//! wraps the typed errors of several layers, so it may name the modules
//! that define them — and those modules never return `crate::Error`
//! themselves (the cycle check below holds them to it).
//!
//! Module uses are read from the whole source of every file: every
//! `crate::a::b` path, every `super::a` path, and `use` lines of
//! submodules (`use self::…` or a submodule's name), outside comments and
//! outside the items marked `#[cfg(test)]` (test modules, test-only
//! functions), wherever they are in the file. A module using an item of
//! one of its ancestors is not an edge: a parent declares its children
//! and their shared types live there.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Top-level modules by layer.
const LAYERS: &[&[&str]] = &[
    &["math", "fs"],
    &["scene"],
    &["accel"],
    &["film"],
    &["integrator"],
    &["output", "metrics", "denoise"],
    &["render"],
    &["run"],
    &["cli"],
];

/// What `error` may use: the modules that define the errors it wraps.
const ERROR_WRAPS: &[&str] = &["scene", "film", "fs", "run", "denoise"];

/// The source of every module, by path (`integrator::wavefront::queue`);
/// `lib` and `main` are the crate root.
fn modules() -> BTreeMap<String, String> {
    fn walk(dir: &Path, prefix: &[String], out: &mut BTreeMap<String, String>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            let name = path.file_stem().unwrap().to_string_lossy().into_owned();
            if path.is_dir() {
                let mut p = prefix.to_vec();
                p.push(name);
                walk(&path, &p, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                let mut p = prefix.to_vec();
                if !["mod", "lib", "main"].contains(&name.as_str()) {
                    p.push(name);
                }
                let text = std::fs::read_to_string(&path).unwrap();
                out.insert(p.join("::"), without_tests_and_comments(&text));
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("src"),
        &[],
        &mut out,
    );
    out
}

/// The one sentence that states the layer order, as the README,
/// `src/lib.rs` and `docs/architecture.md` write it.
fn layer_sentence() -> String {
    let layers: Vec<String> = LAYERS.iter().map(|l| l.join(", ")).collect();
    format!("The layers, in order: {}.", layers.join(" → "))
}

/// `text` without its line comments and without every item marked
/// `#[cfg(test)]` (up to the end of its braces, or its `;`), the rest of
/// the file kept.
fn without_tests_and_comments(text: &str) -> String {
    let mut code = without_comments(text);
    while let Some(start) = code.find("#[cfg(test)]") {
        let end = item_end(&code, start);
        code.replace_range(start..end, "");
    }
    code
}

/// The length of the string or character literal at the start of `s`
/// (0 if there is none: a lifetime is no literal).
fn literal_len(s: &[u8]) -> usize {
    let closing = match s.first() {
        Some(b'"') => b'"',
        Some(b'\'') if s.get(1) == Some(&b'\\') || s.get(2) == Some(&b'\'') => b'\'',
        _ => return 0,
    };
    let mut i = 1;
    while i < s.len() && s[i] != closing {
        i += if s[i] == b'\\' { 2 } else { 1 };
    }
    (i + 1).min(s.len())
}

/// `text` without its line comments (`//` outside literals, to the end
/// of the line).
fn without_comments(text: &str) -> String {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let lit = literal_len(&bytes[i..]);
        if lit > 0 {
            out.extend_from_slice(&bytes[i..i + lit]);
            i += lit;
        } else if bytes[i..].starts_with(b"//") {
            while i < bytes.len() && bytes[i] != b'\n' {
                i += 1;
            }
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).unwrap()
}

/// The end of the item that starts at byte `start`: after its matching
/// closing brace, or after its `;` if that comes before any brace.
/// Literals are skipped (their braces do not count).
fn item_end(code: &str, start: usize) -> usize {
    let bytes = code.as_bytes();
    let mut depth = 0usize;
    let mut i = start;
    while i < bytes.len() {
        let lit = literal_len(&bytes[i..]);
        if lit > 0 {
            i += lit;
            continue;
        }
        match bytes[i] {
            b'{' => depth += 1,
            b'}' => {
                depth -= 1;
                if depth == 0 {
                    return i + 1;
                }
            }
            b';' if depth == 0 => return i + 1,
            _ => {}
        }
        i += 1;
    }
    bytes.len()
}

/// The `::`-separated identifiers that follow each occurrence of `prefix`.
fn paths_after<'a>(text: &'a str, prefix: &str) -> Vec<Vec<&'a str>> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(i) = rest.find(prefix) {
        let before = rest[..i].chars().next_back();
        rest = &rest[i + prefix.len()..];
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        let end = rest
            .find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
            .unwrap_or(rest.len());
        let segs: Vec<&str> = rest[..end].split("::").filter(|s| !s.is_empty()).collect();
        if !segs.is_empty() {
            out.push(segs);
        }
    }
    out
}

/// The module a path names: its longest prefix that is a module.
fn resolve(mods: &BTreeMap<String, String>, segs: &[&str]) -> Option<String> {
    (1..=segs.len())
        .rev()
        .map(|n| segs[..n].join("::"))
        .find(|m| mods.contains_key(m))
}

fn is_ancestor(a: &str, of: &str) -> bool {
    a.is_empty() || of.starts_with(&format!("{a}::"))
}

/// Which modules each module uses.
fn graph() -> BTreeMap<String, BTreeSet<String>> {
    let mods = modules();
    let mut edges = BTreeMap::new();
    for (m, text) in &mods {
        let parent: Vec<&str> = m.split("::").filter(|s| !s.is_empty()).collect();
        let parent = &parent[..parent.len().saturating_sub(1)];
        let mut uses = BTreeSet::new();
        let mut add = |segs: Vec<&str>| {
            if let Some(t) = resolve(&mods, &segs)
                && t != *m
                && !is_ancestor(&t, m)
            {
                uses.insert(t);
            }
        };
        for segs in paths_after(text, "crate::") {
            add(segs);
        }
        for segs in paths_after(text, "super::") {
            let mut full = parent.to_vec();
            full.extend(segs);
            add(full);
        }
        // `use child::…` and `self::child::…` inside a module with children.
        for prefix in ["use ", "self::"] {
            for segs in paths_after(text, prefix) {
                let mut full: Vec<&str> = m.split("::").filter(|s| !s.is_empty()).collect();
                full.extend(segs);
                if let Some(t) = resolve(&mods, &full)
                    && t.len() > m.len()
                {
                    uses.insert(t);
                }
            }
        }
        edges.insert(m.clone(), uses);
    }
    edges
}

fn layer(module: &str) -> Option<usize> {
    let top = module.split("::").next().unwrap();
    LAYERS.iter().position(|l| l.contains(&top))
}

#[test]
fn the_module_graph_is_read() {
    // The test would pass vacuously if it read nothing: check a few known
    // uses, so a change to the reading is noticed.
    let g = graph();
    assert!(g["render"].contains("integrator::wavefront"), "{g:?}");
    assert!(g["integrator::wavefront::bounce"].contains("integrator::wavefront::queue"));
    assert!(g["accel::bvh"].contains("accel::triangle"));
    assert!(g.len() > 30, "only {} modules read", g.len());
}

#[test]
fn test_items_are_cut_and_the_code_after_them_is_read() {
    let text = "use crate::a;\n#[cfg(test)]\nfn helper() { let s = \"}//\"; crate::b::f('{', '\\''); }\n\
                pub fn g() { crate::c::h(); } // crate::d\n\
                #[cfg(test)]\nuse crate::e;\n#[cfg(test)]\nmod tests {\n fn t() { crate::f(); }\n}\n\
                pub fn k() { crate::g::h(); }\n";
    let kept = without_tests_and_comments(text);
    for (path, read) in [
        ("crate::a", true),
        ("crate::b", false),
        ("crate::c", true),
        ("crate::d", false),
        ("crate::e", false),
        ("crate::f", false),
        ("crate::g", true),
    ] {
        assert_eq!(kept.contains(path), read, "{path} in {kept:?}");
    }
}

#[test]
fn the_readme_lib_and_architecture_notes_state_the_tested_layer_order() {
    let sentence = layer_sentence();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for file in ["README.md", "src/lib.rs", "docs/architecture.md"] {
        let text = std::fs::read_to_string(root.join(file)).unwrap();
        // Lines joined, doc-comment markers and backquotes dropped: the
        // sentence may wrap and set the names as code.
        let text = text.replace('`', "");
        let words: Vec<&str> = (text.lines())
            .map(|l| l.trim().trim_start_matches("//!"))
            .flat_map(str::split_whitespace)
            .collect();
        assert!(
            words.join(" ").contains(&sentence),
            "{file} does not state the layer order as the test has it: {sentence:?}"
        );
    }
}

#[test]
fn every_module_uses_only_its_layer_and_earlier_ones() {
    let mut wrong = Vec::new();
    for (m, uses) in graph() {
        let top = m.split("::").next().unwrap();
        for u in uses {
            let u_top = u.split("::").next().unwrap();
            let ok = match (top, layer(&m), layer(&u)) {
                ("error", _, _) => ERROR_WRAPS.contains(&u_top),
                (_, _, None) => u_top == "error",
                (_, Some(a), Some(b)) => b <= a,
                (_, None, Some(_)) => true, // the crate root
            };
            if !ok {
                wrong.push(format!("{m} uses {u}"));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "uses against the layer order:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn no_modules_use_each_other() {
    let g = graph();
    // Tarjan's strongly connected components: any of two or more modules
    // is a cycle.
    struct State<'a> {
        g: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        cycles: Vec<Vec<&'a str>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a str) {
        let i = s.index.len();
        s.index.insert(v, i);
        s.low.insert(v, i);
        s.stack.push(v);
        for w in &s.g[v] {
            let w = w.as_str();
            if !s.index.contains_key(w) {
                visit(s, w);
                let lw = s.low[w];
                let lv = s.low.get_mut(v).unwrap();
                *lv = (*lv).min(lw);
            } else if s.stack.contains(&w) {
                let iw = s.index[w];
                let lv = s.low.get_mut(v).unwrap();
                *lv = (*lv).min(iw);
            }
        }
        if s.low[v] == s.index[v] {
            let mut scc = Vec::new();
            while let Some(w) = s.stack.pop() {
                scc.push(w);
                if w == v {
                    break;
                }
            }
            if scc.len() > 1 {
                s.cycles.push(scc);
            }
        }
    }
    let mut s = State {
        g: &g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        cycles: Vec::new(),
    };
    for v in g.keys() {
        if !s.index.contains_key(v.as_str()) {
            visit(&mut s, v);
        }
    }
    assert!(s.cycles.is_empty(), "module cycles: {:?}", s.cycles);
}

/// The lines of every function in `code` (from `fn` to its closing brace),
/// with its name.
fn function_lengths(code: &str) -> Vec<(String, usize)> {
    let bytes = code.as_bytes();
    let ident = |b: u8| b.is_ascii_alphanumeric() || b == b'_';
    let mut out = Vec::new();
    let mut i = 0;
    while let Some(k) = code[i..].find("fn ") {
        let start = i + k;
        i = start + 3;
        if start > 0 && ident(bytes[start - 1]) {
            continue;
        }
        let name: String = code[i..]
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        let end = item_end(code, start);
        out.push((name, code[start..end].matches('\n').count() + 1));
    }
    out
}

#[test]
fn no_function_in_the_scene_layer_is_over_100_lines() {
    // The scene layer is built through one builder with one front end per
    // format: its functions stay short enough to read (issue 24).
    let code = "fn a() {\n}\nfn b() -> u8 {\n    let s = \"}\";\n    1\n}\n";
    assert_eq!(function_lengths(code), [("a".into(), 2), ("b".into(), 4)]);
    let mut long = Vec::new();
    for (module, code) in modules() {
        if module == "scene" || module.starts_with("scene::") {
            for (name, lines) in function_lengths(&code) {
                if lines > 100 {
                    long.push(format!("{module}::{name}: {lines} lines"));
                }
            }
        }
    }
    assert!(long.is_empty(), "functions over 100 lines: {long:?}");
}
