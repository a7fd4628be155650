//! A term's name lives in its own file: the head of its spec text is a `HEAD` constant in
//! `src/model/terms/`, the registry row and the presets name it, and everything else (model
//! selection, the diagnosis, the report) reaches it through that constant or a spec builder
//! (`table::spec`, `by::spec`). Renaming or adding a term then touches one file and one row.
//! This test reads the production sources for string literals that spell a term's spec text.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use biasctl::ModelSpec;
use biasctl::sim::family::HiddenEffect;

/// Literals that spell a term head but mean something else, each with the reason. An entry
/// that no longer occurs fails the test too, so the list cannot go stale.
const ALLOWED: &[(&str, &str, &str)] = &[
    (
        "history/features.rs",
        "direction",
        "the history feature of that name",
    ),
    (
        "plot/views.rs",
        "direction",
        "the history feature's unit label",
    ),
    (
        "sim/config.rs",
        "direction",
        "the simulator's effect of that name",
    ),
    (
        "sim/config.rs",
        "memory",
        "the simulator's effect of that name",
    ),
    (
        "sim/config.rs",
        "drift",
        "the simulator's effect of that name",
    ),
    (
        "sim/config.rs",
        "table",
        "the sequence names table1 … table7",
    ),
    (
        "report/sections/paper.rs",
        "direction",
        "the paper's phenomenon P2",
    ),
    (
        "report/sections/paper.rs",
        "drift",
        "the paper's phenomenon P7",
    ),
    (
        "log/units.rs",
        "step",
        "the singular of the position unit `steps`",
    ),
    ("plot/svg/series.rs", "step", "a staircase series"),
    (
        "report/sections/discover.rs",
        "step",
        "the column of discovery steps",
    ),
    (
        "report/sections/ladder.rs",
        "step",
        "the column of ladder steps",
    ),
    ("select/ladder.rs", "step", "the column of ladder steps"),
    ("sim/family/effects.rs", "lag", "the hidden effect's name"),
    (
        "sim/family/effects.rs",
        "preisach",
        "the hidden effect's name",
    ),
];

fn src_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// The string literals of Rust source `text` with their line numbers: comments (doc comments
/// too) and char literals skipped, escapes kept as written, raw strings read to their end.
fn string_literals(text: &str) -> Vec<(usize, String)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let (mut i, mut line) = (0, 1);
    while i < b.len() {
        match b[i] {
            b'\n' => {
                line += 1;
                i += 1;
            }
            b'/' if b.get(i + 1) == Some(&b'/') => {
                while i < b.len() && b[i] != b'\n' {
                    i += 1;
                }
            }
            b'/' if b.get(i + 1) == Some(&b'*') => {
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
                        line += usize::from(b[i] == b'\n');
                        i += 1;
                    }
                }
            }
            b'\'' => {
                // A char literal ('x', '\n', '"') or a lifetime ('a): skip either.
                if b.get(i + 1) == Some(&b'\\') {
                    i += 2;
                    while i < b.len() && b[i] != b'\'' {
                        i += 1;
                    }
                    i += 1;
                } else if b.get(i + 2) == Some(&b'\'') {
                    i += 3;
                } else {
                    i += 1;
                }
            }
            b'r' if (b.get(i + 1) == Some(&b'"') || b.get(i + 1) == Some(&b'#'))
                && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_')) =>
            {
                let mut j = i + 1;
                let mut hashes = 0;
                while b.get(j) == Some(&b'#') {
                    hashes += 1;
                    j += 1;
                }
                if b.get(j) != Some(&b'"') {
                    i += 1;
                    continue;
                }
                let start = j + 1;
                let close = format!("\"{}", "#".repeat(hashes));
                let end = text[start..].find(&close).map_or(b.len(), |k| start + k);
                out.push((line, text[start..end].to_string()));
                line += text[start..end].matches('\n').count();
                i = end + close.len();
            }
            b'"' => {
                let start = i + 1;
                let mut j = start;
                while j < b.len() && b[j] != b'"' {
                    j += if b[j] == b'\\' { 2 } else { 1 };
                }
                let end = j.min(b.len());
                out.push((line, text[start..end].to_string()));
                line += text[start..end].matches('\n').count();
                i = end + 1;
            }
            _ => i += 1,
        }
    }
    out
}

/// The text of a production file: up to its first `#[cfg(test)]` module.
fn production_part(text: &str) -> &str {
    let mut at = 0;
    for l in text.split_inclusive('\n') {
        let next = &text[at + l.len()..];
        if l.trim_end() == "#[cfg(test)]" {
            let item = next.trim_start();
            if item.starts_with("mod ") || item.starts_with("pub(crate) mod ") {
                return &text[..at];
            }
        }
        at += l.len();
    }
    text
}

/// Every `.rs` file under `dir`, relative to `src/`.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p.strip_prefix(src_dir()).unwrap().to_path_buf());
            }
        }
    }
    out.sort();
    out
}

/// The term heads, from the `HEAD` constants of `src/model/terms/`.
fn term_heads() -> BTreeSet<String> {
    let mut heads = BTreeSet::new();
    for rel in rust_files(&src_dir().join("model/terms")) {
        let text = std::fs::read_to_string(src_dir().join(&rel)).unwrap();
        for l in text.lines() {
            let l = l.trim();
            if l.starts_with("pub(crate) const ") && l.contains("HEAD: &str = \"") {
                let lit = l.split('"').nth(1).unwrap();
                heads.insert(lit.to_string());
            }
        }
    }
    heads
}

/// Whether `lit` spells a term: a head alone, or a head followed by its arguments (`:`) or by
/// further terms (`,`); a format string such as `table:{}` counts.
fn spells_a_term(lit: &str, heads: &BTreeSet<String>) -> bool {
    heads.iter().any(|h| {
        lit.strip_prefix(h.as_str())
            .is_some_and(|rest| rest.is_empty() || rest.starts_with(':') || rest.starts_with(','))
    })
}

/// Files where a term's name belongs: its own file, the registry, the presets; test files.
fn is_home_of_names(rel: &Path) -> bool {
    let s = rel.to_string_lossy().replace('\\', "/");
    s.starts_with("model/terms/")
        || s == "model/registry.rs"
        || s == "model/preset.rs"
        || s.ends_with("/tests.rs")
        || s.rsplit('/')
            .next()
            .is_some_and(|f| f.starts_with("tests_"))
}

#[test]
fn term_names_are_spelled_only_in_their_own_file_the_registry_and_the_presets() {
    let heads = term_heads();
    assert!(
        heads.len() >= 20 && heads.contains("poly2") && heads.contains("dbins"),
        "the HEAD constants were not found: {heads:?}"
    );
    let mut found = Vec::new();
    let mut used: BTreeSet<(String, String)> = BTreeSet::new();
    for rel in rust_files(&src_dir()) {
        if is_home_of_names(&rel) {
            continue;
        }
        let text = std::fs::read_to_string(src_dir().join(&rel)).unwrap();
        let key = rel.to_string_lossy().replace('\\', "/");
        for (line, lit) in string_literals(production_part(&text)) {
            if !spells_a_term(&lit, &heads) {
                continue;
            }
            if ALLOWED.iter().any(|(f, l, _)| *f == key && *l == lit) {
                used.insert((key.clone(), lit));
            } else {
                found.push(format!("src/{key}:{line}: \"{lit}\""));
            }
        }
    }
    assert!(
        found.is_empty(),
        "term names spelled outside their term's file, the registry and the presets:\n  {}\n\
         Use the term file's HEAD constant (`crate::model::terms::NAME::HEAD`) or its spec \
         builder, or, for a word that only looks like a term, an entry in ALLOWED with the reason.",
        found.join("\n  ")
    );
    let stale: Vec<String> = ALLOWED
        .iter()
        .filter(|(f, l, _)| !used.contains(&(f.to_string(), l.to_string())))
        .map(|(f, l, why)| format!("src/{f}: \"{l}\" ({why})"))
        .collect();
    assert!(
        stale.is_empty(),
        "ALLOWED entries that no longer occur (remove them):\n  {}",
        stale.join("\n  ")
    );
}

#[test]
fn the_literal_reader_sees_strings_and_skips_comments_and_chars() {
    // A self-test on a made-up file, so that a reader that sees nothing cannot pass.
    let text = "// \"dahl\" in a comment\nlet a = \"poly2,dahl\"; let c = '\"'; /* \"seek\" */\n\
                let b = r#\"table:{}\"#; fn f<'a>(x: &'a str) {}\n\"esc\\\"aped\"\n";
    let lits: Vec<(usize, String)> = string_literals(text);
    assert_eq!(
        lits,
        vec![
            (2, "poly2,dahl".to_string()),
            (3, "table:{}".to_string()),
            (4, "esc\\\"aped".to_string()),
        ]
    );
    let heads: BTreeSet<String> = ["poly2", "table", "seek"].map(String::from).into();
    assert!(spells_a_term("poly2,dahl", &heads));
    assert!(spells_a_term("table:{}", &heads));
    assert!(spells_a_term("seek", &heads));
    assert!(!spells_a_term("seek_length", &heads));
    assert!(!spells_a_term("tables", &heads));
    let with_tests = "fn a() {}\n#[cfg(test)]\nmod tests {\n    const X: &str = \"seek\";\n}\n";
    assert_eq!(production_part(with_tests), "fn a() {}\n");
}

#[test]
fn the_family_ground_truth_parses_as_terms() {
    for e in HiddenEffect::ALL {
        if let Some(t) = e.true_term() {
            ModelSpec::parse(t).unwrap_or_else(|err| panic!("{}: `{t}`: {err}", e.name()));
        }
    }
}
