//! What the benchmark commands share, so that every figure in BENCHMARKS.md is measured and
//! written the same way: timing one piece of work (wall time from just before the work to just
//! after it, nothing else inside; medians of repeats are `crate::maths::median`), and the
//! [`Table`] each benchmark fills once and writes as CSV (for plots and scripts) and as a
//! Markdown table (for the terminal and BENCHMARKS.md), and the plots' font and PNG encoding.

use std::path::Path;
use std::time::Instant;

use crate::cli::CliError;

/// Runs `work` once: its result and its wall time, seconds.
pub fn timed<T>(work: impl FnOnce() -> T) -> (T, f64) {
    let start = Instant::now();
    let out = work();
    (out, start.elapsed().as_secs_f64())
}

/// Runs `work` once: its result and its wall time, milliseconds.
pub fn timed_ms<T>(work: impl FnOnce() -> T) -> (T, f64) {
    let (out, s) = timed(work);
    (out, s * 1e3)
}

/// A benchmark's results: named columns, rows of formatted values.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Table {
    columns: Vec<&'static str>,
    /// Which columns are numbers (right-aligned in Markdown).
    numeric: Vec<bool>,
    rows: Vec<Vec<String>>,
}

impl Table {
    /// A table of `columns`; a name ending in `:` marks a numeric column (the `:` is dropped).
    pub fn new(columns: &[&'static str]) -> Table {
        let numeric = columns.iter().map(|c| c.ends_with(':')).collect();
        let columns = columns.iter().map(|c| c.trim_end_matches(':')).collect();
        Table { columns, numeric, rows: Vec::new() }
    }

    /// Adds a row (one value per column; missing ones are empty, extra ones dropped).
    pub fn row(&mut self, values: Vec<String>) {
        let mut values = values;
        values.resize(self.columns.len(), String::new());
        self.rows.push(values);
    }

    /// The rows.
    pub fn rows(&self) -> &[Vec<String>] {
        &self.rows
    }

    /// The header and the rows as CSV (values with a comma or quote are quoted).
    pub fn csv(&self) -> String {
        let quote = |v: &str| {
            if v.contains([',', '"', '\n']) { format!("\"{}\"", v.replace('"', "\"\"")) } else { v.to_string() }
        };
        let line = |values: &mut dyn Iterator<Item = &str>| values.map(quote).collect::<Vec<_>>().join(",") + "\n";
        let mut out = line(&mut self.columns.iter().copied());
        for row in &self.rows {
            out += &line(&mut row.iter().map(String::as_str));
        }
        out
    }

    /// The header line and its alignment line of the Markdown table.
    pub fn markdown_header(&self) -> String {
        let align: Vec<&str> = self.numeric.iter().map(|&n| if n { "---:" } else { "---" }).collect();
        format!("| {} |\n|{}|\n", self.columns.join(" | "), align.join("|"))
    }

    /// Row `k` as a Markdown line.
    pub fn markdown_row(&self, k: usize) -> String {
        format!("| {} |\n", self.rows[k].join(" | "))
    }

    /// The whole Markdown table.
    pub fn markdown(&self) -> String {
        (0..self.rows.len()).fold(self.markdown_header(), |out, k| out + &self.markdown_row(k))
    }

    /// Writes the CSV to `path` atomically (its folder made when missing).
    pub fn write_csv(&self, path: &Path) -> Result<(), CliError> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(CliError::file(dir, "cannot create"))?;
        }
        crate::files::write_atomic(path, self.csv().as_bytes()).map_err(CliError::file(path, "cannot write"))
    }
}

/// The bundled font under plotters' "sans-serif", registered once for every plot.
pub(crate) fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let font: &'static [u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
        // The bundled font is valid; if it were not, labels would be missing, not the plot.
        let _ = plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, font);
    });
}

/// A plot's RGB buffer as PNG bytes.
pub(crate) fn plot_png(w: u32, h: u32, buffer: Vec<u8>) -> Result<Vec<u8>, CliError> {
    let image = image::RgbImage::from_raw(w, h, buffer).ok_or("plot buffer has the wrong size")?;
    let mut png = Vec::new();
    image
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(|e| CliError::Failed(e.into()))?;
    Ok(png)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_table_writes_the_same_rows_as_csv_and_markdown() {
        let mut t = Table::new(&["case", "ms:"]);
        t.row(vec!["a, b".into(), "1.5".into()]);
        t.row(vec!["c".into()]);
        assert_eq!(t.csv(), "case,ms\n\"a, b\",1.5\nc,\n");
        assert_eq!(
            t.markdown_header() + &t.markdown_row(0) + &t.markdown_row(1),
            "| case | ms |\n|---|---:|\n| a, b | 1.5 |\n| c |  |\n"
        );
        let dir = std::env::temp_dir().join(format!("terrafuse-table-{}", std::process::id()));
        let path = dir.join("sub/t.csv");
        t.write_csv(&path).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), t.csv());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_timing_covers_the_work_and_keeps_its_result() {
        let (v, s) = timed(|| {
            std::thread::sleep(std::time::Duration::from_millis(20));
            7
        });
        assert_eq!(v, 7);
        assert!(s >= 0.02, "{s}");
        let ((), ms) = timed_ms(|| std::thread::sleep(std::time::Duration::from_millis(5)));
        assert!(ms >= 5.0, "{ms}");
    }
}
