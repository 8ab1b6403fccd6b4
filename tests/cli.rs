//! The `terrafuse` binary as a user runs it: batch conversions, bad input, and the distortion
//! table against the ECM paper's published figures.

mod common;

use common::{repo_path, terrafuse};

#[test]
fn to_face_and_back_on_every_body() {
    for body in ["wgs84", "moon", "mars", "a=6378137,b=6356752.314245"] {
        let out = terrafuse(&["geo", "to-face", "--body", body], "39.9 41.27\n-90 0\n0 180\n35.0 -135.5\n");
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let text = String::from_utf8(out.stdout).unwrap();
        let faces: Vec<&str> = text.lines().map(|l| l.split(' ').next().unwrap()).collect();
        assert_eq!(faces, ["top", "bottom", "back", "back"], "{body}: {text}");
        let back = terrafuse(&["geo", "from-face", "--body", body], &text);
        assert!(back.status.success());
        let first: Vec<f64> = String::from_utf8(back.stdout)
            .unwrap()
            .lines()
            .next()
            .unwrap()
            .split(' ')
            .map(|f| f.parse().unwrap())
            .collect();
        assert!((first[0] - 39.9).abs() < 1e-12 && (first[1] - 41.27).abs() < 1e-12, "{first:?}");
    }
}

#[test]
fn ecef_conversions_read_files_and_stdin() {
    let out = terrafuse(&["geo", "to-ecef", "--body", "wgs84"], "20 10 100\n");
    let xyz: Vec<f64> = String::from_utf8(out.stdout).unwrap().split_whitespace().map(|f| f.parse().unwrap()).collect();
    // GeographicLib CartConvert: 5904838.6983116427 1041182.3792437945 2167730.9898430901.
    assert!((xyz[0] - 5_904_838.698_311_643).abs() < 1e-8 && (xyz[2] - 2_167_730.989_843_09).abs() < 1e-8, "{xyz:?}");
    let out = terrafuse(&["geo", "from-ecef", "--body", "wgs84"], &format!("{} {} {}\n", xyz[0], xyz[1], xyz[2]));
    let llh: Vec<f64> = String::from_utf8(out.stdout).unwrap().split_whitespace().map(|f| f.parse().unwrap()).collect();
    assert!((llh[0] - 20.0).abs() < 1e-12 && (llh[1] - 10.0).abs() < 1e-12 && (llh[2] - 100.0).abs() < 1e-8, "{llh:?}");
    let landmarks = repo_path("projects/samples/landmarks.txt");
    let out = terrafuse(&["geo", "to-face", "--input", landmarks.to_str().unwrap()], "");
    // The landmark file has four columns (name first): every record is refused, by line number.
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("line 2: 'Erzurum' is not a number"));
}

#[test]
fn bad_input_is_refused_with_line_numbers_and_no_panic() {
    let out = terrafuse(&["geo", "to-face", "--body", "wgs84"], "10 20\nten 20\n91 0\n");
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("line 2: 'ten' is not a number"), "{err}");
    assert!(err.contains("line 3: latitude 91 is outside [-90, 90]"), "{err}");
    assert!(err.contains("2 of 3 records refused"), "{err}");
    assert!(!err.contains("panicked"));
    let out = terrafuse(&["geo", "to-face", "--body", "pluto"], "10 20\n");
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown body 'pluto'"));
    let out = terrafuse(&["geo", "to-face", "--input", "/nonexistent/points.txt"], "");
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot open input file /nonexistent/points.txt"));
    let out = terrafuse(&["geo", "from-face"], "top 0.5\nfront 2 0\n");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("line 1: 1 field(s), need 2") && err.contains("line 2: face coordinates (2, 0) are outside"),
        "{err}"
    );
}

/// Parses the first table of `terrafuse analyze tissot`: label → numeric columns.
fn tissot_rows(text: &str) -> Vec<(String, Vec<String>)> {
    text.lines()
        .skip(3)
        .take_while(|l| !l.trim().is_empty())
        .map(|l| {
            let (label, rest) = l.split_at(36);
            (label.trim().to_string(), rest.split_whitespace().filter(|f| *f != "|").map(str::to_string).collect())
        })
        .collect()
}

#[test]
fn tissot_table_reproduces_the_paper() {
    let out = terrafuse(&["analyze", "tissot", "--samples", "150", "--level", "7"], "");
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let rows = tissot_rows(&text);
    assert_eq!(rows.len(), 5, "{text}");
    let num = |row: usize, col: usize| rows[row].1[col].parse::<f64>().unwrap_or(f64::NAN);
    // columns: ω sup, ω corner, paper ω, area ratio, paper ratio, cells ω, cells area
    // Gnomonic: 31.1° and 5.19 (the paper), both at the corner.
    assert!((num(0, 0) - 31.1).abs() < 0.05 && (num(0, 3) - 5.19).abs() < 0.01, "{text}");
    // Adjusted gnomonic: 31.1° and 1.41.
    assert!((num(1, 0) - 31.1).abs() < 0.05 && (num(1, 3) - 1.41).abs() < 0.01, "{text}");
    // QSC: 24.9° at the corners, equal-area; the supremum lies above the corner value.
    assert!((num(2, 1) - 24.9).abs() < 0.05 && (num(2, 3) - 1.0).abs() < 1e-3, "{text}");
    assert!(num(2, 0) > num(2, 1), "{text}");
    // QTM: π/2 area ratio at the pole (closed form of the lat/lon midpoint octant).
    assert!((num(3, 3) - std::f64::consts::FRAC_PI_2).abs() < 0.01, "{text}");
    // Lat/lon faces with polar caps: degenerate pointwise, and its cells vary by far the most.
    assert_eq!(rows[4].1[0], "degen.");
    assert!(num(4, 6) > 10.0 * num(0, 6), "{text}");
}

#[test]
fn an_error_prints_its_cause_chain() {
    // A project whose layer names a store that is a file but not a database: the message names
    // the project, the layer and the store, then what SQLite said.
    let dir = common::scratch("cause-chain");
    let store = dir.join("broken.gpkg");
    let mut bytes = b"SQLite format 3\0".to_vec();
    bytes.extend([0xff; 4000]);
    std::fs::write(&store, bytes).unwrap();
    let project = dir.join("p.json");
    let text = r#"{"format": "terrafuse-project", "version": 4, "body": "moon",
        "layers": [{"name": "dem", "kind": "dataset", "store": "broken.gpkg"},
                   {"name": "other", "kind": "dataset", "store": "broken.gpkg"}]}"#;
    std::fs::write(&project, text).unwrap();
    let out = terrafuse(&["compare", project.to_str().unwrap(), "dem", "other", "--json"], "");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("layer 'dem'") && err.contains("broken.gpkg"), "{err}");
    assert!(err.contains("is not a Terrafuse store") && err.contains("file is not a database"), "{err}");
    // A project that is a folder: the file system's words come after the file's name.
    let out = terrafuse(&["render", dir.to_str().unwrap(), "--out", dir.join("x.png").to_str().unwrap()], "");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("cannot read") && err.contains("os error"), "{err}");
}

/// The `terrafuse` command line, as main.rs parses it.
#[derive(clap::Parser)]
struct Cli {
    #[command(subcommand)]
    command: terrafuse::cli::args::Command,
}

/// The command lines the README and docs/ quote: every line of a code block and every inline
/// code span that starts with `terrafuse ` (a line ending in `\` joined with the next), with the
/// file and line they come from.
fn documented_command_lines() -> Vec<(String, String)> {
    let mut files = vec![common::repo_path("README.md")];
    let mut docs: Vec<_> = std::fs::read_dir(common::repo_path("docs"))
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    files.extend(docs);
    let mut out = Vec::new();
    for file in files {
        let text = std::fs::read_to_string(&file).unwrap();
        let name = file.file_name().unwrap().to_string_lossy().into_owned();
        let mut in_code = false;
        let mut joined = String::new();
        for (k, line) in text.lines().enumerate() {
            let at = format!("{name}:{}", k + 1);
            if line.trim_start().starts_with("```") {
                in_code = !in_code;
                continue;
            }
            if in_code {
                let line = line.split(" # ").next().unwrap_or("").trim();
                if !joined.is_empty() || line.starts_with("terrafuse ") {
                    joined.push_str(line.trim_end_matches('\\'));
                    joined.push(' ');
                    if !line.ends_with('\\') {
                        out.push((at, std::mem::take(&mut joined)));
                    }
                }
                continue;
            }
            for (i, span) in line.split('`').enumerate() {
                if i % 2 == 1 && span.starts_with("terrafuse ") {
                    out.push((at.clone(), span.to_string()));
                }
            }
        }
    }
    out
}

#[test]
fn every_command_line_the_docs_quote_names_commands_and_flags_that_exist() {
    use clap::CommandFactory;
    let root = Cli::command();
    let lines = documented_command_lines();
    assert!(lines.len() > 50, "the docs quote command lines: {}", lines.len());
    let mut problems = Vec::new();
    for (at, line) in &lines {
        let words: Vec<&str> = line.split_whitespace().skip(1).collect();
        // The subcommands named (`a|b` names each of several), then the flags of the last.
        let mut command = &root;
        let mut chain: Vec<&clap::Command> = vec![&root];
        let mut rest = &words[..];
        while let Some(word) = rest.first() {
            let names: Vec<&str> = word.split('|').collect();
            if !names.iter().all(|n| n.chars().all(|c| c.is_ascii_lowercase() || c == '-') && !n.is_empty()) {
                break;
            }
            let Some(found) = command.find_subcommand(names[0]) else { break };
            for n in &names[1..] {
                if command.find_subcommand(n).is_none() {
                    problems.push(format!("{at}: `{line}`: no subcommand '{n}'"));
                }
            }
            command = found;
            chain.push(found);
            rest = &rest[1..];
        }
        for word in rest {
            let Some(flag) = word.strip_prefix("--") else { continue };
            let flag = flag.split(['=', '|', '`', ',', ')', ']']).next().unwrap_or("");
            if flag.is_empty() || flag == "help" || flag == "version" || !flag.chars().next().unwrap().is_alphabetic() {
                continue;
            }
            let known = chain.iter().any(|c| c.get_arguments().any(|a| a.get_long() == Some(flag)));
            if !known {
                problems.push(format!("{at}: `{}`: no flag --{flag}", line.trim()));
            }
        }
    }
    assert!(problems.is_empty(), "documented command lines that do not exist:\n{}", problems.join("\n"));
}
