//! Benchmark results as CSV files that runs append to and resume from: a row whose key
//! columns are already present is not measured again.

use std::collections::BTreeMap;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result, bail};

/// One CSV file: a header, key columns (which identify a measurement) and rows.
pub struct ResultTable {
    path: PathBuf,
    pub columns: Vec<String>,
    key_columns: usize,
    pub rows: Vec<Vec<String>>,
}

fn escape(v: &str) -> String {
    if v.contains([',', '"', '\n']) {
        format!("\"{}\"", v.replace('"', "\"\""))
    } else {
        v.to_string()
    }
}

fn split_csv_line(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                cur.push('"');
                chars.next();
            }
            ('"', _) => quoted = !quoted,
            (',', false) => out.push(std::mem::take(&mut cur)),
            _ => cur.push(c),
        }
    }
    out.push(cur);
    out
}

impl ResultTable {
    /// Opens `path` (creating it with `columns` if missing). The first `key_columns` columns
    /// identify a row. An existing file with other columns is an error (delete it to rerun).
    pub fn open(path: &Path, columns: &[&str], key_columns: usize) -> Result<ResultTable> {
        let columns: Vec<String> = columns.iter().map(|c| c.to_string()).collect();
        let mut rows = Vec::new();
        if path.exists() {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading {}", path.display()))?;
            let mut lines = text.lines();
            let header = lines.next().map(split_csv_line).unwrap_or_default();
            if header != columns {
                bail!(
                    "{} has the columns {:?}, this version writes {:?}; move it away to start afresh",
                    path.display(),
                    header,
                    columns
                );
            }
            for (i, line) in lines.enumerate() {
                if line.trim().is_empty() {
                    continue;
                }
                let row = split_csv_line(line);
                if row.len() != columns.len() {
                    bail!(
                        "{}:{}: expected {} values, found {}",
                        path.display(),
                        i + 2,
                        columns.len(),
                        row.len()
                    );
                }
                rows.push(row);
            }
        } else {
            if let Some(dir) = path.parent() {
                std::fs::create_dir_all(dir)
                    .with_context(|| format!("creating {}", dir.display()))?;
            }
            let mut f = std::fs::File::create(path)
                .with_context(|| format!("creating {}", path.display()))?;
            writeln!(
                f,
                "{}",
                columns
                    .iter()
                    .map(|c| escape(c))
                    .collect::<Vec<_>>()
                    .join(",")
            )?;
        }
        Ok(ResultTable {
            path: path.to_path_buf(),
            columns,
            key_columns,
            rows,
        })
    }

    /// The row with these key values, if already measured.
    pub fn get(&self, key: &[String]) -> Option<&Vec<String>> {
        self.rows
            .iter()
            .find(|r| r[..self.key_columns] == key[..self.key_columns])
    }

    pub fn has(&self, key: &[String]) -> bool {
        self.get(key).is_some()
    }

    /// Appends a row and writes it to disk at once, so an interrupted run keeps it.
    pub fn push(&mut self, row: Vec<String>) -> Result<()> {
        if row.len() != self.columns.len() {
            bail!(
                "internal: a row of {} values for {} columns",
                row.len(),
                self.columns.len()
            );
        }
        let mut f = std::fs::OpenOptions::new()
            .append(true)
            .open(&self.path)
            .with_context(|| format!("appending to {}", self.path.display()))?;
        writeln!(
            f,
            "{}",
            row.iter().map(|c| escape(c)).collect::<Vec<_>>().join(",")
        )?;
        self.rows.push(row);
        Ok(())
    }

    pub fn column(&self, name: &str) -> Result<usize> {
        self.columns
            .iter()
            .position(|c| c == name)
            .with_context(|| format!("no column {name:?} in {}", self.path.display()))
    }

    /// Rows as maps from column name to value.
    pub fn records(&self) -> Vec<BTreeMap<&str, &str>> {
        self.rows
            .iter()
            .map(|r| {
                self.columns
                    .iter()
                    .map(|c| c.as_str())
                    .zip(r.iter().map(|v| v.as_str()))
                    .collect()
            })
            .collect()
    }

    /// The whole table in Markdown.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "| {} |\n|{}|\n",
            self.columns.join(" | "),
            vec!["---"; self.columns.len()].join("|")
        );
        for r in &self.rows {
            s.push_str(&format!("| {} |\n", r.join(" | ")));
        }
        s
    }
}

/// The distinct values of `column` over `records`, in order of first appearance.
pub fn distinct<'t, 'r>(
    records: impl IntoIterator<Item = &'r BTreeMap<&'t str, &'t str>>,
    column: &str,
) -> Vec<&'t str>
where
    't: 'r,
{
    let mut out: Vec<&'t str> = Vec::new();
    for r in records {
        if let Some(&v) = r.get(column)
            && !out.contains(&v)
        {
            out.push(v);
        }
    }
    out
}

/// Formats a float for a table: 4 significant digits.
pub fn num(v: f64) -> String {
    if !v.is_finite() {
        return if v.is_nan() {
            "nan".into()
        } else if v > 0.0 {
            "inf".into()
        } else {
            "-inf".into()
        };
    }
    if v == 0.0 {
        return "0".into();
    }
    let digits = (4 - 1 - v.abs().log10().floor() as i32).max(0) as usize;
    format!("{v:.digits$}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distinct_keeps_the_order_of_first_appearance() {
        let rows: Vec<BTreeMap<&str, &str>> = [("b", "x"), ("a", "y"), ("b", "z"), ("c", "x")]
            .iter()
            .map(|&(s, m)| BTreeMap::from([("scene", s), ("method", m)]))
            .collect();
        assert_eq!(distinct(&rows, "scene"), ["b", "a", "c"]);
        assert_eq!(distinct(&rows, "method"), ["x", "y", "z"]);
        assert!(distinct(&rows, "missing").is_empty());
    }

    #[test]
    fn rows_survive_reopening_and_quotes_round_trip() {
        let dir = std::env::temp_dir().join(format!("noisefree-table-{}", std::process::id()));
        let path = dir.join("t.csv");
        let _ = std::fs::remove_file(&path);
        let mut t = ResultTable::open(&path, &["scene", "kw", "ms"], 2).unwrap();
        t.push(vec!["a,b".into(), "7".into(), "1.5".into()])
            .unwrap();
        t.push(vec!["say \"x\"".into(), "9".into(), "2".into()])
            .unwrap();
        let t2 = ResultTable::open(&path, &["scene", "kw", "ms"], 2).unwrap();
        assert_eq!(t2.rows, t.rows);
        assert!(t2.has(&["a,b".into(), "7".into()]));
        assert!(!t2.has(&["a,b".into(), "8".into()]));
        assert!(ResultTable::open(&path, &["other"], 1).is_err());
    }

    #[test]
    fn numbers_keep_four_significant_digits() {
        assert_eq!(num(1234.5678), "1235");
        assert_eq!(num(0.012345), "0.01235");
        assert_eq!(num(f64::INFINITY), "inf");
    }
}
