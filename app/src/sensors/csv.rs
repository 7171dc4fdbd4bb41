//! Reading trace files: CSV with a header row, comma-separated, one record per line. Blank
//! lines and lines starting with `#` are skipped. Every error names the file and the line.
//! Shared by [`crate::pose::trace`] (truth traces) and [`super::replay`] (sensor traces).

use anyhow::{Context, Result, bail};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// A parsed CSV file: the header and the records with their 1-based line numbers.
#[derive(Debug)]
pub struct Table {
    path: PathBuf,
    columns: HashMap<String, usize>,
    records: Vec<(usize, Vec<String>)>,
}

/// One record of a [`Table`]; its accessors produce errors naming file, line and column.
pub struct Record<'a> {
    table: &'a Table,
    pub line: usize,
    fields: &'a [String],
}

impl Table {
    /// Read `path`, requiring every column in `required` to be in the header (any order; extra
    /// columns are ignored). An empty file, a header without records, a record with the wrong
    /// number of fields: errors.
    pub fn read(path: &Path, required: &[&str]) -> Result<Table> {
        let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
        Self::parse(path, &text, required)
    }

    /// Parse CSV text as if read from `path` (used for error messages).
    pub fn parse(path: &Path, text: &str, required: &[&str]) -> Result<Table> {
        let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim())).filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
        let Some((header_line, header)) = lines.next() else {
            bail!("{}: empty file (expected a header: {})", path.display(), required.join(","));
        };
        let names: Vec<String> = header.split(',').map(|s| s.trim().to_ascii_lowercase()).collect();
        let mut columns = HashMap::new();
        for (i, n) in names.iter().enumerate() {
            if columns.insert(n.clone(), i).is_some() {
                bail!("{}:{header_line}: column '{n}' appears twice in the header", path.display());
            }
        }
        let missing: Vec<&str> = required.iter().copied().filter(|c| !columns.contains_key(*c)).collect();
        if !missing.is_empty() {
            bail!(
                "{}:{header_line}: missing column(s) {} (header is '{header}', expected {})",
                path.display(),
                missing.join(", "),
                required.join(",")
            );
        }
        let mut records = Vec::new();
        for (line, l) in lines {
            let fields: Vec<String> = l.split(',').map(|s| s.trim().to_string()).collect();
            if fields.len() != names.len() {
                bail!("{}:{line}: {} fields, but the header has {} columns", path.display(), fields.len(), names.len());
            }
            records.push((line, fields));
        }
        if records.is_empty() {
            bail!("{}: no records after the header", path.display());
        }
        Ok(Table { path: path.to_path_buf(), columns, records })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn has_column(&self, name: &str) -> bool {
        self.columns.contains_key(name)
    }

    pub fn records(&self) -> impl Iterator<Item = Record<'_>> {
        self.records.iter().map(|(line, fields)| Record { table: self, line: *line, fields })
    }

    pub fn len(&self) -> usize {
        self.records.len()
    }

    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }
}

impl Record<'_> {
    /// "file:line" for messages.
    pub fn at(&self) -> String {
        format!("{}:{}", self.table.path.display(), self.line)
    }

    /// The raw text of a column (empty string for an empty cell).
    pub fn text(&self, column: &str) -> Result<&str> {
        let Some(&i) = self.table.columns.get(column) else {
            bail!("{}: no column '{column}'", self.at());
        };
        Ok(self.fields[i].as_str())
    }

    /// A finite number; empty cells, text, NaN and infinities are errors.
    pub fn number(&self, column: &str) -> Result<f64> {
        match self.optional_number(column)? {
            Some(v) => Ok(v),
            None => bail!("{}: column '{column}' is empty", self.at()),
        }
    }

    /// A finite number or `None` for an empty cell.
    pub fn optional_number(&self, column: &str) -> Result<Option<f64>> {
        let s = self.text(column)?;
        if s.is_empty() {
            return Ok(None);
        }
        let v: f64 = s.parse().map_err(|_| anyhow::anyhow!("{}: column '{column}': '{s}' is not a number", self.at()))?;
        if !v.is_finite() {
            bail!("{}: column '{column}' is {s} (NaN and infinities are not allowed)", self.at());
        }
        Ok(Some(v))
    }
}

/// The longest gap between consecutive records (seconds). Replays step through a trace at a
/// fixed rate, so a gap of 10⁷ s would be hours of frames of nothing; a longer pause is a broken
/// recording.
pub const MAX_TIME_GAP_S: f64 = 60.0;

/// Require timestamps to increase strictly from record to record, by at most
/// [`MAX_TIME_GAP_S`].
pub fn check_time_increases(rec: &Record<'_>, previous: Option<f64>, t: f64) -> Result<()> {
    if let Some(p) = previous {
        if t - p > MAX_TIME_GAP_S {
            bail!("{}: time jumps {} s ({p} to {t}); at most {MAX_TIME_GAP_S} s between records", rec.at(), t - p);
        }
        if t < p {
            bail!("{}: time goes backwards ({t} after {p})", rec.at());
        }
        if t == p {
            bail!("{}: time does not advance ({t} repeated)", rec.at());
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Table> {
        Table::parse(Path::new("x.csv"), text, &["t", "a"])
    }

    #[test]
    fn header_any_order_comments_and_blank_lines() {
        let t = parse("# comment\nA,T\n\n1,2\n3,4\n").unwrap();
        let recs: Vec<_> = t.records().collect();
        assert_eq!(recs.len(), 2);
        assert_eq!(recs[0].number("t").unwrap(), 2.0);
        assert_eq!(recs[1].line, 5);
    }

    #[test]
    fn errors_name_file_line_and_reason() {
        let e = parse("").unwrap_err().to_string();
        assert!(e.contains("x.csv") && e.contains("empty file"), "{e}");
        let e = parse("t,a\n").unwrap_err().to_string();
        assert!(e.contains("no records"), "{e}");
        let e = parse("t,b\n1,2\n").unwrap_err().to_string();
        assert!(e.contains("x.csv:1") && e.contains("missing column(s) a"), "{e}");
        let e = parse("t,a\n1\n").unwrap_err().to_string();
        assert!(e.contains("x.csv:2") && e.contains("1 fields"), "{e}");
        let t = parse("t,a\n1,NaN\n2,x\n3,\n").unwrap();
        let recs: Vec<_> = t.records().collect();
        let e = recs[0].number("a").unwrap_err().to_string();
        assert!(e.contains("x.csv:2") && e.contains("NaN"), "{e}");
        let e = recs[1].number("a").unwrap_err().to_string();
        assert!(e.contains("x.csv:3") && e.contains("'x' is not a number"), "{e}");
        assert!(recs[2].optional_number("a").unwrap().is_none());
        assert!(recs[2].number("a").is_err());
        let e = check_time_increases(&recs[1], Some(5.0), 2.0).unwrap_err().to_string();
        assert!(e.contains("x.csv:3") && e.contains("backwards"), "{e}");
        assert!(check_time_increases(&recs[1], Some(2.0), 2.0).is_err());
        assert!(check_time_increases(&recs[1], Some(1.0), 2.0).is_ok());
        let e = check_time_increases(&recs[1], Some(1.0), 1e7).unwrap_err().to_string();
        assert!(e.contains("x.csv:3") && e.contains("at most 60 s"), "{e}");
        assert!(check_time_increases(&recs[1], Some(1.0), 61.0).is_ok());
    }

    #[test]
    fn duplicate_columns_are_errors() {
        assert!(parse("t,a,t\n1,2,3\n").is_err());
    }
}
