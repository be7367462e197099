//! The library's layers go one way. Each top-level module of `tools/src` may name (`crate::m`)
//! only modules of lower layers, so that a change to one concept does not ripple back through
//! the modules built on it. `error` is the crate's one error enum, which every layer returns and
//! which names every layer's error: it is the contract, not a layer, and is left out.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// Bottom first; modules in one layer may not name each other.
const LAYERS: &[&[&str]] = &[
    &["linalg", "progress", "output"],
    &["set"],
    &["cylinder_chain"],
    &["skinning"],
    &["import", "train"],
    &["eval"],
    &["export", "run"],
    // The binary's commands (main.rs): they name the library as `rrskin_tools`.
    &["cli"],
];

fn layer(module: &str) -> Option<usize> {
    LAYERS.iter().position(|l| l.contains(&module))
}

fn sources(path: &Path, out: &mut Vec<PathBuf>) {
    if path.is_dir() {
        for entry in std::fs::read_dir(path).expect("a source folder") {
            sources(&entry.expect("a folder entry").path(), out);
        }
    } else if path.extension().is_some_and(|e| e == "rs") {
        out.push(path.to_path_buf());
    }
}

/// The top-level modules `text` names: `crate::m` and `crate::{m, …}`.
fn named(text: &str) -> BTreeSet<String> {
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect()
    };
    let mut out = BTreeSet::new();
    for (at, _) in text.match_indices("crate::") {
        let rest = &text[at + "crate::".len()..];
        match rest.strip_prefix('{') {
            Some(group) => {
                let group = &group[..group.find('}').unwrap_or(group.len())];
                out.extend(group.split(',').map(|p| ident(p.trim())));
            }
            None => {
                out.insert(ident(rest));
            }
        }
    }
    out.retain(|m| m.chars().next().is_some_and(|c| c.is_ascii_lowercase()));
    out
}

#[test]
fn every_module_names_only_lower_layers() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut violations = Vec::new();
    let mut seen = BTreeSet::new();
    for entry in std::fs::read_dir(&src).expect("tools/src") {
        let path = entry.expect("a folder entry").path();
        let module = path
            .file_stem()
            .expect("a named file")
            .to_string_lossy()
            .to_string();
        if matches!(module.as_str(), "lib" | "main" | "error") {
            continue;
        }
        let own = layer(&module).unwrap_or_else(|| panic!("{module}: in no layer of LAYERS"));
        seen.insert(module.clone());
        let mut files = Vec::new();
        sources(&path, &mut files);
        for file in files {
            let text = std::fs::read_to_string(&file).expect("a source file");
            for other in named(&text) {
                if other == module || other == "error" {
                    continue;
                }
                match layer(&other) {
                    Some(l) if l < own => {}
                    _ => violations.push(format!(
                        "{}: names crate::{other} (layer {:?}) from {module} (layer {own})",
                        file.strip_prefix(&src).unwrap_or(&file).display(),
                        layer(&other)
                    )),
                }
            }
        }
    }
    assert!(violations.is_empty(), "{}", violations.join("\n"));
    let listed: BTreeSet<String> = LAYERS
        .iter()
        .flat_map(|l| l.iter().map(|m| m.to_string()))
        .collect();
    assert_eq!(seen, listed, "LAYERS lists a module that is not there");
}

#[test]
fn the_scanner_sees_both_forms() {
    let text =
        "use crate::set::ExampleSet;\nuse crate::{train::ssd, skinning};\nlet e = crate::Error::X;";
    let found: Vec<String> = named(text).into_iter().collect();
    assert_eq!(found, ["set", "skinning", "train"]);
}
