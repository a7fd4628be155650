//! The library's layers are a fact, not a comment: `src/lib.rs` declares the top-level modules in
//! pipeline order, and no production code imports a module declared after its own, nor does any
//! set of files import each other in a circle. The check reads the source itself: every
//! `crate::…` and `super::…` path outside comments and outside test code (a `#[cfg(test)]`
//! module, inline or in its own file) is an import of the module file it names.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A module path: `["fit", "solve"]` for `src/fit/solve.rs`.
type ModPath = Vec<String>;

fn src_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// The top-level modules in the order `src/lib.rs` declares them.
fn lib_order(lib: &str) -> Vec<String> {
    lib.lines()
        .filter_map(|l| {
            let l = l.trim();
            let rest = l
                .strip_prefix("pub(crate) mod ")
                .or_else(|| l.strip_prefix("pub mod "))
                .or_else(|| l.strip_prefix("mod "))?;
            rest.strip_suffix(';').map(str::to_string)
        })
        .collect()
}

/// The text with comments blanked, string and char literals emptied (their contents are no
/// imports), lines kept.
fn code_only(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        if c == b'/' && b.get(i + 1) == Some(&b'/') {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if c == b'/' && b.get(i + 1) == Some(&b'*') {
            let mut depth = 0;
            while i < b.len() {
                if b[i] == b'/' && b.get(i + 1) == Some(&b'*') {
                    depth += 1;
                    i += 2;
                } else if b[i] == b'*' && b.get(i + 1) == Some(&b'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    if b[i] == b'\n' {
                        out.push('\n');
                    }
                    i += 1;
                }
            }
        } else if c == b'r' && (b.get(i + 1) == Some(&b'"') || b.get(i + 1) == Some(&b'#')) && {
            // A raw string r"…" / r#"…"#, not an identifier ending in r.
            let prev = if i == 0 { b' ' } else { b[i - 1] };
            !(prev.is_ascii_alphanumeric() || prev == b'_')
        } {
            let mut j = i + 1;
            let mut hashes = 0;
            while b.get(j) == Some(&b'#') {
                hashes += 1;
                j += 1;
            }
            if b.get(j) != Some(&b'"') {
                out.push('r');
                i += 1;
                continue;
            }
            j += 1;
            loop {
                if j >= b.len() {
                    break;
                }
                if b[j] == b'"' && (0..hashes).all(|k| b.get(j + 1 + k) == Some(&b'#')) {
                    j += 1 + hashes;
                    break;
                }
                if b[j] == b'\n' {
                    out.push('\n');
                }
                j += 1;
            }
            out.push_str("\"\"");
            i = j;
        } else if c == b'"' {
            i += 1;
            while i < b.len() && b[i] != b'"' {
                if b[i] == b'\\' {
                    i += 1;
                }
                if i < b.len() && b[i] == b'\n' {
                    out.push('\n');
                }
                i += 1;
            }
            i += 1;
            out.push_str("\"\"");
        } else if c == b'\'' {
            // A char literal ('x', '\n', '\u{..}') or a lifetime ('a): skip only a literal.
            let close = if b.get(i + 1) == Some(&b'\\') {
                b[i + 2..]
                    .iter()
                    .position(|&x| x == b'\'')
                    .map(|p| i + 2 + p)
            } else if b.get(i + 2) == Some(&b'\'') {
                Some(i + 2)
            } else {
                std::str::from_utf8(&b[i + 1..])
                    .ok()
                    .and_then(|s| s.chars().next())
                    .filter(|ch| !ch.is_ascii())
                    .map(|ch| i + 1 + ch.len_utf8())
                    .filter(|&e| b.get(e) == Some(&b'\''))
            };
            match close {
                Some(e) => {
                    out.push_str("' '");
                    i = e + 1;
                }
                None => {
                    out.push('\'');
                    i += 1;
                }
            }
        } else {
            let ch = text[i..].chars().next().unwrap();
            out.push(ch);
            i += ch.len_utf8();
        }
    }
    out
}

/// Removes `#[cfg(test)]` items that are modules (inline `mod x { … }`) and collects the names
/// of test-only module files (`#[cfg(test)] mod x;`).
fn strip_tests(code: &str, test_children: &mut BTreeSet<String>) -> String {
    let mut out = String::with_capacity(code.len());
    let mut rest = code;
    while let Some(at) = rest.find("#[cfg(test)]") {
        out.push_str(&rest[..at]);
        let after = &rest[at + "#[cfg(test)]".len()..];
        let trimmed = after.trim_start();
        let item = trimmed
            .strip_prefix("pub(crate) ")
            .or_else(|| trimmed.strip_prefix("pub(super) "))
            .or_else(|| trimmed.strip_prefix("pub "))
            .unwrap_or(trimmed);
        if let Some(m) = item.strip_prefix("mod ") {
            let name: String = m
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            let tail = m[name.len()..].trim_start();
            if let Some(after_semi) = tail.strip_prefix(';') {
                test_children.insert(name);
                rest = after_semi;
                continue;
            }
            if tail.starts_with('{') {
                // Skip the module's braces.
                let start = m.len() - tail.len();
                let body = &m[start..];
                let mut depth = 0usize;
                let mut end = body.len();
                for (k, ch) in body.char_indices() {
                    match ch {
                        '{' => depth += 1,
                        '}' => {
                            depth -= 1;
                            if depth == 0 {
                                end = k + 1;
                                break;
                            }
                        }
                        _ => {}
                    }
                }
                rest = &body[end..];
                continue;
            }
        }
        // Another test-only item (a function, a use): it is test code too, but only modules
        // hold test imports in this crate; keep the text.
        out.push_str("#[cfg(test)]");
        rest = after;
    }
    out.push_str(rest);
    out
}

/// The module path of a source file relative to `src/`.
fn mod_path(rel: &Path) -> ModPath {
    let mut parts: Vec<String> = rel
        .with_extension("")
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if parts.last().is_some_and(|p| p == "mod") {
        parts.pop();
    }
    parts
}

/// Every `crate::a::b` / `super::a` path in `code`, resolved to a module path (not yet cut to
/// an existing module file). Braced groups `crate::{a, b::c}` give one path per member.
fn paths_in(code: &str, here: &ModPath) -> Vec<Vec<String>> {
    let mut found = Vec::new();
    let b = code.as_bytes();
    let ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    let mut i = 0;
    while i < b.len() {
        let starts = |kw: &str| {
            code[i..].starts_with(kw)
                && (i == 0 || !ident(b[i - 1]))
                && code[i + kw.len()..].starts_with("::")
        };
        let (base, kw_len): (Vec<String>, usize) = if starts("crate") {
            (Vec::new(), 5)
        } else if starts("super") {
            // `super` from a file `a/b.rs` (module a::b) is `a`; from `a/mod.rs` (module a) it
            // is the crate root. Nested `super::super` is handled below.
            let mut p = here.clone();
            p.pop();
            (p, 5)
        } else {
            i += 1;
            continue;
        };
        let mut j = i + kw_len;
        let mut path = base;
        while code[j..].starts_with("::") {
            j += 2;
            if code[j..].starts_with('{') {
                // A group: each member at depth 1 starts a path.
                let mut depth = 0;
                let mut member = String::new();
                let mut k = j;
                while k < b.len() {
                    let ch = b[k] as char;
                    match ch {
                        '{' => {
                            depth += 1;
                            if depth > 1 {
                                member.push(ch);
                            }
                        }
                        '}' => {
                            depth -= 1;
                            if depth == 0 {
                                break;
                            }
                            member.push(ch);
                        }
                        ',' if depth == 1 => {
                            push_member(&mut found, &path, &member);
                            member.clear();
                        }
                        _ => member.push(ch),
                    }
                    k += 1;
                }
                push_member(&mut found, &path, &member);
                path.clear();
                j = k;
                break;
            }
            let seg: String = code[j..]
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            if seg.is_empty() {
                break;
            }
            j += seg.len();
            if seg == "super" {
                path.pop();
            } else {
                path.push(seg);
            }
        }
        if !path.is_empty() {
            found.push(path);
        }
        i = j.max(i + 1);
    }
    found
}

fn push_member(found: &mut Vec<Vec<String>>, prefix: &[String], member: &str) {
    let first: Vec<String> = member
        .trim()
        .split("::")
        .map(|s| {
            s.trim()
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect::<String>()
        })
        .take_while(|s| !s.is_empty() && s != "self")
        .collect();
    if first.is_empty() && prefix.is_empty() {
        return;
    }
    let mut p = prefix.to_vec();
    p.extend(first);
    if !p.is_empty() {
        found.push(p);
    }
}

/// The code of a file split by inline modules (`mod avx2 { … }`): each piece with the module
/// path its `super::` is relative to. Test modules were removed before.
fn inline_pieces(code: &str, here: &ModPath) -> Vec<(ModPath, String)> {
    let mut pieces = Vec::new();
    let mut outer = String::with_capacity(code.len());
    let mut rest = code;
    loop {
        let Some(at) = find_inline_mod(rest) else {
            outer.push_str(rest);
            break;
        };
        let (name_start, open) = at;
        outer.push_str(&rest[..name_start]);
        let name: String = rest[name_start + 4..]
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        let mut depth = 0usize;
        let mut end = rest.len();
        for (k, ch) in rest[open..].char_indices() {
            match ch {
                '{' => depth += 1,
                '}' => {
                    depth -= 1;
                    if depth == 0 {
                        end = open + k + 1;
                        break;
                    }
                }
                _ => {}
            }
        }
        let mut inner = here.clone();
        inner.push(name);
        pieces.extend(inline_pieces(
            &rest[open + 1..end.saturating_sub(1)],
            &inner,
        ));
        rest = &rest[end..];
    }
    pieces.push((here.clone(), outer));
    pieces
}

/// The first `mod NAME {` in `code`: the index of `mod ` and of its `{`.
fn find_inline_mod(code: &str) -> Option<(usize, usize)> {
    let b = code.as_bytes();
    let mut from = 0;
    while let Some(p) = code[from..].find("mod ") {
        let at = from + p;
        from = at + 4;
        if at > 0 && (b[at - 1].is_ascii_alphanumeric() || b[at - 1] == b'_') {
            continue;
        }
        let name_len = code[at + 4..]
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .count();
        let after = &code[at + 4 + name_len..];
        let trimmed = after.trim_start();
        if name_len > 0 && trimmed.starts_with('{') {
            return Some((at, at + 4 + name_len + (after.len() - trimmed.len())));
        }
    }
    None
}

struct Source {
    /// Module path → file (relative to src/), production code only.
    files: BTreeMap<ModPath, (PathBuf, String)>,
}

fn read_sources() -> Source {
    let src = src_dir();
    let mut all: Vec<PathBuf> = Vec::new();
    let mut stack = vec![src.clone()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                all.push(p);
            }
        }
    }
    all.sort();
    let mut tests: BTreeSet<ModPath> = BTreeSet::new();
    let mut files = BTreeMap::new();
    for p in &all {
        let rel = p.strip_prefix(&src).unwrap().to_path_buf();
        if rel == Path::new("main.rs") || rel == Path::new("lib.rs") {
            continue;
        }
        let here = mod_path(&rel);
        let mut test_children = BTreeSet::new();
        let code = strip_tests(
            &code_only(&std::fs::read_to_string(p).unwrap()),
            &mut test_children,
        );
        // Children of a mod.rs are `here::child`; of a.rs (non-mod) they are `a::child` too.
        for c in test_children {
            let mut m = here.clone();
            m.push(c);
            tests.insert(m);
        }
        files.insert(here, (rel, code));
    }
    // Drop test-only files and everything below them.
    files.retain(|m, _| !tests.iter().any(|t| m.starts_with(t)));
    Source { files }
}

/// The file a path refers to: its longest prefix that is a module file.
fn owner<'a>(
    files: &'a BTreeMap<ModPath, (PathBuf, String)>,
    path: &[String],
) -> Option<&'a ModPath> {
    (1..=path.len())
        .rev()
        .find_map(|k| files.get_key_value(&path[..k]).map(|(m, _)| m))
}

fn edges(src: &Source) -> BTreeMap<ModPath, BTreeSet<ModPath>> {
    let mut out: BTreeMap<ModPath, BTreeSet<ModPath>> = BTreeMap::new();
    for (here, (_, code)) in &src.files {
        let set = out.entry(here.clone()).or_default();
        for (scope, piece) in inline_pieces(code, here) {
            for p in paths_in(&piece, &scope) {
                if let Some(m) = owner(&src.files, &p)
                    && m != here
                {
                    set.insert(m.clone());
                }
            }
        }
    }
    out
}

fn show(m: &ModPath) -> String {
    m.join("::")
}

#[test]
fn no_module_imports_one_declared_after_it() {
    let lib = std::fs::read_to_string(src_dir().join("lib.rs")).unwrap();
    let order = lib_order(&lib);
    assert!(
        order.len() > 5,
        "read the module order of src/lib.rs: {order:?}"
    );
    let rank = |m: &ModPath| order.iter().position(|o| *o == m[0]);
    let src = read_sources();
    let mut upward = Vec::new();
    for (from, tos) in edges(&src) {
        for to in tos {
            if let (Some(a), Some(b)) = (rank(&from), rank(&to))
                && b > a
            {
                upward.push(format!(
                    "src/{} imports crate::{} (`{}` is declared after `{}` in src/lib.rs)",
                    src.files[&from].0.display(),
                    show(&to),
                    to[0],
                    from[0]
                ));
            }
        }
    }
    assert!(
        upward.is_empty(),
        "{} import(s) point up the pipeline:\n  {}\nA module may import only modules declared \
         before it in src/lib.rs. Move the item that both need down to the lower module (or \
         into a lower layer such as `numeric` or `io`), or move the code that needs the higher \
         module up; do not reorder lib.rs to hide a circle.",
        upward.len(),
        upward.join("\n  ")
    );
}

/// The one circle by design: `scale` wraps any other term (`scale:COL:TERM`), so its parser
/// and restorer call the registry's, which lists `scale` among the terms. Any other circle
/// fails the test.
const RECURSIVE_BY_DESIGN: &[&str] = &[
    "src/model/registry.rs",
    "src/model/terms/mod.rs",
    "src/model/terms/scale.rs",
];

#[test]
fn no_circle_of_files() {
    let src = read_sources();
    let g = edges(&src);
    // Tarjan's strongly connected components, iteratively small: the graph has ~200 nodes.
    let nodes: Vec<&ModPath> = src.files.keys().collect();
    let idx: BTreeMap<&ModPath, usize> = nodes.iter().enumerate().map(|(i, m)| (*m, i)).collect();
    let adj: Vec<Vec<usize>> = nodes
        .iter()
        .map(|m| {
            g.get(*m)
                .map(|s| s.iter().filter_map(|t| idx.get(t).copied()).collect())
                .unwrap_or_default()
        })
        .collect();
    let n = nodes.len();
    let mut circles: Vec<Vec<String>> = Vec::new();
    fn visit(
        v: usize,
        adj: &[Vec<usize>],
        st: &mut (Vec<usize>, Vec<usize>, Vec<bool>, Vec<usize>, usize),
        out: &mut Vec<Vec<usize>>,
    ) {
        st.0[v] = st.4;
        st.1[v] = st.4;
        st.4 += 1;
        st.3.push(v);
        st.2[v] = true;
        for &w in &adj[v] {
            if st.0[w] == usize::MAX {
                visit(w, adj, st, out);
                st.1[v] = st.1[v].min(st.1[w]);
            } else if st.2[w] {
                st.1[v] = st.1[v].min(st.0[w]);
            }
        }
        if st.1[v] == st.0[v] {
            let mut comp = Vec::new();
            loop {
                let w = st.3.pop().unwrap();
                st.2[w] = false;
                comp.push(w);
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                out.push(comp);
            }
        }
    }
    // (index, low link, on stack, stack, next index) of Tarjan's algorithm.
    let mut st = (
        vec![usize::MAX; n],
        vec![0; n],
        vec![false; n],
        Vec::new(),
        0,
    );
    let mut comps = Vec::new();
    for v in 0..n {
        if st.0[v] == usize::MAX {
            visit(v, &adj, &mut st, &mut comps);
        }
    }
    for c in comps {
        let mut names: Vec<String> = c
            .iter()
            .map(|&i| format!("src/{}", src.files[nodes[i]].0.display()))
            .collect();
        names.sort();
        if names == RECURSIVE_BY_DESIGN {
            continue;
        }
        circles.push(names);
    }
    assert!(
        circles.is_empty(),
        "files that import each other in a circle:\n  {}\nBreak each circle: move what the \
         lower file needs from the higher one into the lower file, or into a third file both \
         import.",
        circles
            .iter()
            .map(|c| c.join(" ↔ "))
            .collect::<Vec<_>>()
            .join("\n  ")
    );
}

#[test]
fn the_checker_sees_imports_and_skips_comments_strings_and_tests() {
    // A self-test on a made-up file, so that a checker that sees nothing cannot pass.
    let text = "use crate::fit::{solve::Qr, FitOptions};\n// crate::report::x\nlet s = \"crate::plot\";\n\
                fn f() { super::sibling::g(); crate::model::{self, Term}; }\n#[cfg(test)]\nmod tests {\n    use crate::cli::run;\n}\n";
    let mut kids = BTreeSet::new();
    let code = strip_tests(&code_only(text), &mut kids);
    let here: ModPath = vec!["diagnose".into(), "features".into()];
    let paths = paths_in(&code, &here);
    let flat: Vec<String> = paths.iter().map(|p| p.join("::")).collect();
    assert!(flat.contains(&"fit::solve::Qr".to_string()), "{flat:?}");
    assert!(flat.contains(&"fit::FitOptions".to_string()), "{flat:?}");
    assert!(
        flat.contains(&"diagnose::sibling::g".to_string()),
        "{flat:?}"
    );
    assert!(flat.contains(&"model".to_string()), "{flat:?}");
    assert!(flat.contains(&"model::Term".to_string()), "{flat:?}");
    assert!(
        !flat
            .iter()
            .any(|p| p.starts_with("report") || p.starts_with("plot") || p.starts_with("cli")),
        "{flat:?}"
    );
    let pieces = inline_pieces(
        "use super::a;\nmod avx2 {\n    fn f() { super::lanes(); }\n}\n",
        &here,
    );
    let scoped: Vec<String> = pieces
        .iter()
        .flat_map(|(scope, code)| paths_in(code, scope))
        .map(|p| p.join("::"))
        .collect();
    assert!(
        scoped.contains(&"diagnose::features::lanes".to_string()),
        "{scoped:?}"
    );
    assert!(scoped.contains(&"diagnose::a".to_string()), "{scoped:?}");
    let mut kids = BTreeSet::new();
    let _ = strip_tests("#[cfg(test)]\nmod tests;\n", &mut kids);
    assert!(kids.contains("tests"));
    assert_eq!(
        lib_order("pub(crate) mod field;\n#[cfg(feature = \"cli\")]\npub mod cli;\n"),
        ["field", "cli"]
    );
}

/// Longest production part of a source file, in lines (its text before a `#[cfg(test)]`
/// module; test files declared `#[cfg(test)] mod NAME;` do not count).
const MAX_FILE_LINES: usize = 800;

#[test]
fn no_production_file_over_800_lines() {
    let src = read_sources();
    let mut long: Vec<String> = src
        .files
        .values()
        .filter_map(|(rel, _)| {
            let text = std::fs::read_to_string(src_dir().join(rel)).unwrap();
            let mut lines = 0;
            let mut prev_cfg_test = false;
            for l in text.lines() {
                let t = l.trim_start();
                if prev_cfg_test
                    && l == t
                    && (t.starts_with("mod ") || t.starts_with("pub(crate) mod "))
                {
                    lines -= 1; // the attribute line belongs to the tests
                    break;
                }
                prev_cfg_test = l == "#[cfg(test)]";
                lines += 1;
            }
            (lines > MAX_FILE_LINES).then(|| format!("src/{} ({lines} lines)", rel.display()))
        })
        .collect();
    long.sort();
    assert!(
        long.is_empty(),
        "production files over {MAX_FILE_LINES} lines:\n  {}\nSplit each by concern into a folder \
         (`foo.rs` → `foo/{{mod.rs, a.rs, b.rs}}`, re-exported from `foo/mod.rs`); tests may move \
         to a `tests.rs` beside it.",
        long.join("\n  ")
    );
}

/// Longest production function, in lines from its `fn` line to its closing brace (rustfmt's
/// layout; a nested function counts in its parent too).
const MAX_FN_LINES: usize = 150;

/// Every function body in `code` (comments and literals already blanked): its name, the line
/// its `fn` stands on (1-based) and its length in lines. A declaration without a body (a trait
/// method's `;`) and a function-pointer type (`fn(f64) -> f64`) are not functions.
fn functions(code: &str) -> Vec<(String, usize, usize)> {
    let b = code.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while let Some(k) = code[i..].find("fn ") {
        let at = i + k;
        i = at + 3;
        if at > 0 && (b[at - 1].is_ascii_alphanumeric() || b[at - 1] == b'_') {
            continue;
        }
        let name: String = code[at + 3..]
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        if name.is_empty() {
            continue;
        }
        // The body's `{` (or a `;`) at parenthesis and bracket depth 0 after the signature.
        let mut depth = 0i32;
        let mut open = None;
        for (j, &c) in b.iter().enumerate().skip(at) {
            match c {
                b'(' | b'[' => depth += 1,
                b')' | b']' => depth -= 1,
                b';' if depth == 0 => break,
                b'{' if depth == 0 => {
                    open = Some(j);
                    break;
                }
                _ => {}
            }
        }
        let Some(open) = open else { continue };
        let mut braces = 0usize;
        let mut close = b.len() - 1;
        for (j, &c) in b.iter().enumerate().skip(open) {
            match c {
                b'{' => braces += 1,
                b'}' => {
                    braces -= 1;
                    if braces == 0 {
                        close = j;
                        break;
                    }
                }
                _ => {}
            }
        }
        let line = code[..at].matches('\n').count() + 1;
        let lines = code[at..=close].matches('\n').count() + 1;
        out.push((name, line, lines));
    }
    out
}

#[test]
fn no_production_function_over_150_lines() {
    let src = read_sources();
    let mut long: Vec<String> = src
        .files
        .values()
        .flat_map(|(rel, code)| {
            functions(code)
                .into_iter()
                .filter(|(_, _, lines)| *lines > MAX_FN_LINES)
                .map(move |(name, line, lines)| {
                    format!("src/{}:{line} `{name}` ({lines} lines)", rel.display())
                })
        })
        .collect();
    long.sort();
    assert!(
        long.is_empty(),
        "production functions over {MAX_FN_LINES} lines:\n  {}\nSplit each into steps named for \
         what they do.",
        long.join("\n  ")
    );
}

#[test]
fn the_function_reader_measures_bodies_and_skips_declarations_and_pointer_types() {
    let code = "trait T {\n    fn declared(&self) -> u8;\n}\nfn outer(f: fn(f64) -> f64, \
                a: [u8; 2]) -> u8 {\n    fn inner() {}\n    let x = {\n        1\n    };\n    x\n}\n\
                pub(crate) fn one_line() -> Vec<u8> { vec![] }\nfn ends_in_where<T>(t: T)\nwhere\n    \
                T: Copy,\n{\n}\n";
    let got = functions(code);
    assert_eq!(
        got,
        [
            ("outer".to_string(), 4, 7),
            ("inner".to_string(), 5, 1),
            ("one_line".to_string(), 11, 1),
            ("ends_in_where".to_string(), 12, 5),
        ]
    );
}
