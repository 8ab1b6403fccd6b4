//! The module graph, read from the source: every `crate::MODULE` a library file names (outside
//! comments and its unit tests) must be one its module may import, and no two files of one
//! module may import each other, directly or round a longer loop. The allowed graph below is the
//! one ARCHITECTURE.md draws; change both together. Library code (everything but `main.rs`)
//! neither prints nor reads environment variables.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

mod common;

/// What each top-level module of `src/` may import. Bottom to top: shared helpers, the maths,
/// the store, the edits and the layer stack, the project, the CPU scene, the GPU, the
/// comparison and replay, and the two front ends (which never import each other).
const ALLOWED: &[(&str, &[&str])] = &[
    ("errors", &[]),
    ("files", &[]),
    ("progress", &[]),
    ("maths", &[]),
    ("slurm", &[]),
    ("colour", &[]),
    ("geodesy", &["errors"]),
    ("attributes", &["errors", "maths", "geodesy"]),
    ("ecm", &["errors", "maths", "geodesy"]),
    ("store", &["errors", "files", "progress", "maths", "geodesy", "ecm"]),
    // The edits, erosion and the layer stack are maths over the cube map's grid (ecm::grid,
    // ecm::area_mean): they never name the store, whose GDAL and SQLite they do not need; the
    // scene reads the store for them (its loader).
    ("edit", &["errors", "files", "progress", "maths", "geodesy", "ecm"]),
    ("erosion", &["errors", "files", "progress", "maths", "geodesy", "ecm", "edit"]),
    ("layers", &["errors", "files", "progress", "maths", "geodesy", "ecm", "edit", "erosion"]),
    (
        "project",
        &[
            "errors",
            "files",
            "progress",
            "maths",
            "colour",
            "geodesy",
            "attributes",
            "ecm",
            "store",
            "edit",
            "erosion",
            "layers",
        ],
    ),
    // What every command's shard plan shares: the inputs' stamps, the hash, the cut.
    ("plan", &["files", "project"]),
    (
        "scene",
        &[
            "errors", "files", "progress", "maths", "colour", "geodesy", "ecm", "store", "edit", "erosion", "layers",
            "project",
        ],
    ),
    (
        "compare",
        &[
            "attributes",
            "errors",
            "files",
            "progress",
            "maths",
            "colour",
            "geodesy",
            "ecm",
            "store",
            "edit",
            "erosion",
            "layers",
            "project",
            "plan",
            "scene",
        ],
    ),
    (
        "gpu",
        &[
            "attributes",
            "errors",
            "files",
            "progress",
            "maths",
            "colour",
            "geodesy",
            "ecm",
            "store",
            "edit",
            "erosion",
            "layers",
            "project",
            "scene",
        ],
    ),
    (
        "replay",
        &[
            "attributes",
            "errors",
            "files",
            "progress",
            "maths",
            "colour",
            "geodesy",
            "ecm",
            "store",
            "edit",
            "erosion",
            "layers",
            "project",
            "scene",
            "gpu",
        ],
    ),
    // A project's composed stack written as a GeoTIFF, band by band: what the command line and,
    // one day, the workstation export.
    ("export", &["gpu", "compare", "plan"]),
    (
        "gui",
        &[
            "attributes",
            "errors",
            "files",
            "progress",
            "maths",
            "colour",
            "geodesy",
            "ecm",
            "store",
            "edit",
            "erosion",
            "layers",
            "project",
            "scene",
            "gpu",
            "compare",
            "replay",
            "slurm",
            "export",
        ],
    ),
    (
        "cli",
        &[
            "attributes",
            "errors",
            "files",
            "progress",
            "maths",
            "colour",
            "geodesy",
            "ecm",
            "store",
            "edit",
            "erosion",
            "layers",
            "project",
            "scene",
            "gpu",
            "compare",
            "replay",
            "slurm",
            "export",
        ],
    ),
    // The benchmarks sit above the command line whose plumbing (errors, console, renderer
    // opening) they use; the command line never imports them.
    ("bench", &["cli"]),
];

/// Paths a module may not name even where it may import the module: the renderer draws what
/// the scene loaded and never imports, shards or plans.
const FORBIDDEN: &[(&str, &str)] =
    &[("gpu", "crate::store::import"), ("gpu", "crate::store::shard"), ("gpu", "crate::store::merge")];

/// The text of a file without its comments and without its `#[cfg(test)] mod …` (unit tests may
/// reach wherever a test needs to).
fn code_of(text: &str) -> String {
    let code: Vec<&str> = text.lines().filter(|l| !l.trim_start().starts_with("//")).collect();
    let code = code.join("\n");
    match code.find("#[cfg(test)]\nmod ") {
        Some(i) => code[..i].to_string(),
        None => code,
    }
}

/// The identifiers that follow `prefix` in `code` (`crate::` → `store`, `gpu`, …).
fn names_after<'a>(code: &'a str, prefix: &str) -> Vec<&'a str> {
    code.match_indices(prefix)
        .filter(|(i, _)| !code[..*i].ends_with(|c: char| c.is_alphanumeric() || c == '_'))
        .map(|(i, _)| {
            let rest = &code[i + prefix.len()..];
            let end = rest.find(|c: char| !(c.is_alphanumeric() || c == '_')).unwrap_or(rest.len());
            &rest[..end]
        })
        .collect()
}

/// Every `.rs` file under `dir`, recursively, sorted.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    out.sort();
    out
}

/// The top-level module a file of `src/` belongs to (`src/store/gpkg.rs` → `store`), or None for
/// the crate root and the binary.
fn module_of(src: &Path, file: &Path) -> Option<String> {
    let rel = file.strip_prefix(src).unwrap();
    let first = rel.components().next()?.as_os_str().to_string_lossy().into_owned();
    let name = first.trim_end_matches(".rs").to_string();
    (name != "lib" && name != "main").then_some(name)
}

/// What each module may import: its arrows in ALLOWED and, through them, everything its targets
/// may (the table lists a module after everything it points to).
fn allowed_closure() -> BTreeMap<&'static str, BTreeSet<&'static str>> {
    let mut allowed: BTreeMap<&str, BTreeSet<&str>> = BTreeMap::new();
    for (m, deps) in ALLOWED {
        let mut may: BTreeSet<&str> = deps.iter().copied().collect();
        for d in *deps {
            may.extend(allowed.get(d).into_iter().flatten().copied());
        }
        allowed.insert(m, may);
    }
    allowed
}

#[test]
fn every_module_imports_only_what_the_architecture_allows() {
    let src = common::repo_path("src");
    let allowed = allowed_closure();
    let mut problems = Vec::new();
    let mut seen_modules = BTreeSet::new();
    for file in rust_files(&src) {
        let Some(module) = module_of(&src, &file) else { continue };
        if file.file_name().is_some_and(|n| n == "tests.rs") {
            continue;
        }
        seen_modules.insert(module.clone());
        let Some(may) = allowed.get(module.as_str()) else {
            problems.push(format!("{}: module '{module}' is not in the allowed graph", file.display()));
            continue;
        };
        let code = code_of(&std::fs::read_to_string(&file).unwrap());
        for target in names_after(&code, "crate::") {
            if target != module && allowed.contains_key(target) && !may.contains(target) {
                problems.push(format!("{}: '{module}' may not import '{target}'", file.display()));
            }
        }
        for (m, path) in FORBIDDEN {
            if *m == module && code.contains(path) {
                problems.push(format!("{}: '{module}' may not name {path}", file.display()));
            }
        }
    }
    // Every module of src/ is in the table, and the table names no module that is gone.
    let listed: BTreeSet<String> = allowed.keys().map(|m| m.to_string()).collect();
    assert_eq!(seen_modules, listed, "the allowed graph and src/ list different modules");
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn library_code_neither_prints_nor_reads_the_environment() {
    // Only the binary talks to the terminal and the environment; the library returns text and
    // takes what main.rs read (a trace level, a log callback, a configuration folder).
    let src = common::repo_path("src");
    let mut problems = Vec::new();
    for file in rust_files(&src) {
        if module_of(&src, &file).is_none() || file.file_name().is_some_and(|n| n == "tests.rs") {
            continue;
        }
        let code = code_of(&std::fs::read_to_string(&file).unwrap());
        for (k, line) in code.lines().enumerate() {
            let prints = ["println!", "eprintln!", "print!(", "eprint!(", "dbg!("].iter().any(|m| line.contains(m));
            let reads_env = line.contains("env::var");
            if prints || reads_env {
                problems.push(format!("{}:{}: {}", file.display(), k + 1, line.trim()));
            }
        }
    }
    assert!(problems.is_empty(), "library code that prints or reads the environment:\n{}", problems.join("\n"));
}

#[test]
fn the_allowed_graph_has_no_cycle() {
    // Each module may import only modules listed before it: the table is a topological order.
    for (k, (module, deps)) in ALLOWED.iter().enumerate() {
        for d in *deps {
            let at = ALLOWED.iter().position(|(m, _)| m == d).unwrap_or_else(|| panic!("{module}: unknown '{d}'"));
            assert!(at < k, "'{module}' may import '{d}', which comes after it");
        }
    }
}

#[test]
fn no_two_files_of_a_module_import_each_other() {
    let src = common::repo_path("src");
    let mut problems = Vec::new();
    for entry in std::fs::read_dir(&src).unwrap() {
        let dir = entry.unwrap().path();
        if !dir.is_dir() {
            continue;
        }
        let module = dir.file_name().unwrap().to_string_lossy().into_owned();
        // The module's own files and folders: its submodules.
        let subs: BTreeSet<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path().file_stem().unwrap().to_string_lossy().into_owned())
            .filter(|s| s != "mod" && s != "tests")
            .collect();
        let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for file in rust_files(&dir) {
            let rel = file.strip_prefix(&dir).unwrap();
            let parts: Vec<String> = rel.components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
            let me = parts[0].trim_end_matches(".rs").to_string();
            if me == "mod" || me == "tests" || parts.last().is_some_and(|p| p == "tests.rs") {
                continue;
            }
            let code = code_of(&std::fs::read_to_string(&file).unwrap());
            let mut refs: BTreeSet<String> =
                names_after(&code, &format!("crate::{module}::")).into_iter().map(str::to_string).collect();
            // `super::` names a sibling from a submodule's own file (`a.rs` or `a/mod.rs`).
            if parts.len() == 1 || (parts.len() == 2 && parts[1] == "mod.rs") {
                refs.extend(names_after(&code, "super::").into_iter().map(str::to_string));
            }
            refs.retain(|r| subs.contains(r) && *r != me);
            graph.entry(me).or_default().extend(refs);
        }
        for (a, targets) in &graph {
            for b in targets {
                // Does b reach a?
                let mut seen = BTreeSet::new();
                let mut stack = vec![b.clone()];
                while let Some(x) = stack.pop() {
                    for y in graph.get(&x).into_iter().flatten() {
                        if seen.insert(y.clone()) {
                            stack.push(y.clone());
                        }
                    }
                }
                if seen.contains(a) {
                    problems.push(format!("{module}: {a} and {b} import each other"));
                }
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn library_errors_are_typed_not_strings() {
    // A failure a caller may act on is a value of a thiserror type, never a `Result<_, String>`:
    // a string can only be shown, not matched, and its causes are lost (issue 52); nor a pair of
    // strings for a field and its problem (`errors::FieldProblem`). Nor is an
    // error flattened into words on its way up (`map_err(|e| format!(…))`): it goes under a field
    // (`errors::AtField`, `Invalid::at`) or a context that keeps it as the cause (`within`,
    // `context`), or becomes a typed error of its own.
    let src = common::repo_path("src");
    let mut problems = Vec::new();
    for file in rust_files(&src) {
        if module_of(&src, &file).is_none() {
            continue;
        }
        let code = code_of(&std::fs::read_to_string(&file).unwrap());
        for (k, line) in code.lines().enumerate() {
            let squeezed: String = line.chars().filter(|c| !c.is_whitespace()).collect();
            // Nor a (field, problem) pair of strings, which callers took apart by matching the
            // field's name: `errors::FieldProblem`.
            if squeezed.contains("Result<") && (squeezed.contains(",String>") || squeezed.contains(",String)>")) {
                problems.push(format!("{}:{}: {}", file.display(), k + 1, line.trim()));
            }
        }
        // The closure's body may start on the next line.
        let squeezed: String = code.chars().filter(|c| !c.is_whitespace()).collect();
        for (at, _) in squeezed.match_indices("map_err(|") {
            let rest = &squeezed[at + "map_err(|".len()..];
            let body = rest.find('|').map(|bar| rest[bar + 1..].trim_start_matches('{'));
            if body.is_some_and(|b| b.starts_with("format!(")) {
                problems.push(format!("{}: {}", file.display(), squeezed[at..].chars().take(60).collect::<String>()));
            }
        }
    }
    assert!(problems.is_empty(), "errors returned as strings:\n{}", problems.join("\n"));
}
