//! The documentation against the code: every built-in term has its row in the term table of
//! `docs/models-and-terms.md` (README links to that table), and every local link in README,
//! ARCHITECTURE.md and `docs/` points at a file that exists.

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read(rel: &str) -> String {
    std::fs::read_to_string(root().join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

/// The head of a term's syntax as the registry lists it (`table[:SPACING]` → `table`,
/// `dahl:N` → `dahl`, `stribeck[:COL][:DELTA]` → `stribeck`).
fn head(syntax: &str) -> &str {
    syntax.split([':', '[']).next().unwrap_or(syntax).trim()
}

/// Reference: the term registry (`biasctl::model::builtin_names`, the list a spec error and
/// `fit --help` print). Each head must start a row of the term table: a line `| `HEAD…` under
/// the heading "Built-in terms" of docs/models-and-terms.md.
#[test]
fn every_built_in_term_has_a_row_in_the_term_table() {
    let doc = read("docs/models-and-terms.md");
    let table: Vec<&str> = doc
        .split("\n## ")
        .find(|s| s.starts_with("Built-in terms"))
        .expect("docs/models-and-terms.md has a section `## Built-in terms`")
        .lines()
        .filter(|l| l.starts_with("| `"))
        .collect();
    let names = biasctl::model::builtin_names();
    let mut missing = Vec::new();
    for syntax in names.split(", ") {
        let h = head(syntax);
        let row = format!("| `{h}");
        let found = table
            .iter()
            .any(|l| l.starts_with(&row) && l[row.len()..].starts_with(['`', ':', '[', ',']));
        if !found {
            missing.push(h.to_string());
        }
    }
    assert!(
        missing.is_empty(),
        "built-in terms without a row in the term table of docs/models-and-terms.md: {missing:?} \
         (add one row each: `| \\`SYNTAX\\` | what it models |`)"
    );
    let readme = read("README.md");
    assert!(
        readme.contains("docs/models-and-terms.md#built-in-terms"),
        "README links to the term table (docs/models-and-terms.md#built-in-terms)"
    );
}

/// Relative link targets of a Markdown text: `](target)` with no scheme, the `#anchor` cut.
fn local_links(text: &str) -> Vec<String> {
    text.split("](")
        .skip(1)
        .filter_map(|s| s.split(')').next())
        .map(|t| t.split('#').next().unwrap_or("").to_string())
        .filter(|t| !t.is_empty() && !t.contains("://") && !t.starts_with("mailto:"))
        .collect()
}

/// Reference: the file system. A moved or renamed file leaves no dead link behind.
#[test]
fn local_links_in_the_documentation_resolve() {
    let mut files = vec![root().join("README.md"), root().join("ARCHITECTURE.md")];
    for dir in ["docs", "benches", "data/real"] {
        for e in std::fs::read_dir(root().join(dir)).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "md") {
                files.push(p);
            }
        }
    }
    let mut dead = Vec::new();
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        let base = f.parent().unwrap_or(Path::new("."));
        for target in local_links(&text) {
            if !base.join(&target).exists() {
                dead.push(format!("{}: {target}", f.display()));
            }
        }
    }
    assert!(dead.is_empty(), "dead links: {dead:#?}");
}
