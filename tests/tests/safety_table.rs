//! `docs/safety.md` keeps its promise: every row of the hazard table names at least one test
//! function, and every named function exists in the repository's sources (a Rust `fn` or a
//! Python `def`). A cell still saying `TODO-` fails, as does a name that was renamed away.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// The repository's root (this crate is one level below it).
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the tests crate sits in the repository")
        .to_path_buf()
}

/// Every function name defined in the `.rs` and `.py` files under `dir` (build outputs and
/// hidden folders skipped).
fn defined_functions(dir: &Path, out: &mut BTreeSet<String>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') || name == "target" || name == "node_modules" {
            continue;
        }
        if path.is_dir() {
            defined_functions(&path, out);
            continue;
        }
        let keyword = match path.extension().and_then(|e| e.to_str()) {
            Some("rs") => "fn ",
            Some("py") => "def ",
            _ => continue,
        };
        let Ok(text) = std::fs::read_to_string(&path) else {
            continue;
        };
        for line in text.lines() {
            let mut rest = line;
            while let Some(at) = rest.find(keyword) {
                let after = &rest[at + keyword.len()..];
                let ident: String = after
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                    .collect();
                if !ident.is_empty() {
                    out.insert(ident);
                }
                rest = after;
            }
        }
    }
}

/// The rows of the table under `## The table`: (hazard, test cell).
fn rows(doc: &str) -> Vec<(String, String)> {
    let Some(start) = doc.find("## The table") else {
        return Vec::new();
    };
    let table = &doc[start..];
    let table = table[1..]
        .find("\n## ")
        .map_or(table, |end| &table[..end + 1]);
    table
        .lines()
        .filter(|l| l.starts_with('|'))
        .map(|l| {
            l.trim()
                .trim_matches('|')
                .split('|')
                .map(|c| c.trim().to_string())
                .collect::<Vec<_>>()
        })
        // The header and its separator.
        .filter(|cells| {
            cells
                .first()
                .is_some_and(|c| c != "hazard" && !c.starts_with("---"))
        })
        .map(|cells| {
            (
                cells.first().cloned().unwrap_or_default(),
                cells.last().cloned().unwrap_or_default(),
            )
        })
        .collect()
}

/// The back-quoted names of a cell.
fn named(cell: &str) -> Vec<String> {
    cell.split('`')
        .skip(1)
        .step_by(2)
        .map(str::to_string)
        .collect()
}

/// What is wrong with the table `doc` against the functions `defined`, one line each.
fn problems(doc: &str, defined: &BTreeSet<String>) -> Vec<String> {
    let rows = rows(doc);
    if rows.is_empty() {
        return vec!["no hazard table found under `## The table`".into()];
    }
    let mut out = Vec::new();
    for (hazard, cell) in rows {
        if cell.contains("TODO-") {
            out.push(format!("`{hazard}`: the test cell is still {cell:?}"));
            continue;
        }
        let names = named(&cell);
        if names.is_empty() {
            out.push(format!("`{hazard}`: no test named in {cell:?}"));
        }
        for name in names {
            if !defined.contains(&name) {
                out.push(format!("`{hazard}`: no function `{name}` in the sources"));
            }
        }
    }
    out
}

#[test]
fn every_row_of_the_hazard_table_names_tests_that_exist() {
    let doc = std::fs::read_to_string(root().join("docs/safety.md")).expect("docs/safety.md");
    let mut defined = BTreeSet::new();
    defined_functions(&root(), &mut defined);
    assert!(
        defined.contains("every_row_of_the_hazard_table_names_tests_that_exist"),
        "the source walk found nothing"
    );
    let rows = rows(&doc);
    assert!(rows.len() >= 18, "only {} rows", rows.len());
    let problems = problems(&doc, &defined);
    assert!(
        problems.is_empty(),
        "docs/safety.md:\n{}",
        problems.join("\n")
    );
}

#[test]
fn the_check_refuses_a_todo_a_missing_name_and_an_empty_cell() {
    let defined: BTreeSet<String> = ["real_test".to_string()].into();
    let doc = "## The table\n\n\
        | hazard | detection | safe state | bound | test |\n\
        |---|---|---|---|---|\n\
        | fine | d | s | b | `real_test` |\n\
        | pending | d | s | b | TODO-safety-rt |\n\
        | renamed | d | s | b | `real_test`, `gone_test` |\n\
        | untested | d | s | b | none |\n\
        \n## After\n| not | a | row | of | it |\n";
    let found = problems(doc, &defined);
    assert_eq!(found.len(), 3, "{found:#?}");
    assert!(found[0].contains("pending") && found[0].contains("TODO-"));
    assert!(found[1].contains("gone_test"));
    assert!(found[2].contains("untested"));
    assert_eq!(problems("no table", &defined).len(), 1);
}
