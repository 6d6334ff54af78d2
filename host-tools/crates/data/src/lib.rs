//! Measurement CSV reader for axcomp (contract: `../shared/spec/interfaces.md`, "Measurement CSV").
//!
//! Terms:
//! - *dataset*: the rows of one measurement CSV after `--rename`, `--scale` and `--where`, with every cell
//!   kept as text and, for columns whose cells all read as numbers, as `f64`.
//! - *source*: the name used in messages (the path as the user gave it).
//! - *line*: the physical line (1-based) of the file on which a row starts; *column*: 1-based field index.
//! - *alias*: a second accepted name of a contract column: `cycle` for `run`, `approach_direction` for
//!   `direction`. A lookup by either name finds the column the file has under the other (so `--cv cycle`
//!   works on a file with `run`, `--holdout run=2` on one with `cycle`); a column of the asked name wins.
//! - *sensor*: a `*_degC` column; its name is the part before the suffix.
//! - *error channel*: a `*_um` column (`deviation_um`, `ch3_um`, ...).
//! - *holdout*: rows held out from fitting (`--holdout`), *group*: rows sharing a value of a column (`--cv`).
//!
//! Rules:
//! - `#` comment lines may precede the header; blank lines are skipped; fields follow RFC 4180 quoting.
//! - A duplicate header, a ragged row or an unterminated quote is an error at load, naming file, line and
//!   column. A separator at the end of every line (an empty last header field, empty last cells) adds
//!   no column. A file separated by `;` or tabs, with CR-only line ends or in UTF-16 is refused saying so.
//! - Numbers: a cell is numeric if Rust's `f64` parser accepts it after trimming (`1`, `-2.5e-3`, `NaN`,
//!   `inf`). An explicit `NaN` is a deliberate "no value" and is kept; an **empty cell is not a number**:
//!   [`Dataset::numeric`] on a column with an empty or non-numeric cell fails naming the first such cell.
//!   [`Dataset::numeric_or_nan`] reads such a column leniently (empty/text → NaN) for optional channels.
//! - Order of the options: `--rename` first, then the `time` → `time_s` conversion, then `--scale`, then
//!   `--where`. `time_s` is relative to the first row of the file (before `--where`).

mod builder;
mod cells;
mod csv;
pub mod provenance;
pub mod sanity;
mod split;
mod timestamp;

pub use provenance::Provenance;
pub use split::{HoldoutSpec, Split, groups};

use std::path::Path;

use builder::Builder;
use cells::Cells;

/// Everything that can be wrong with a measurement file or with the options that select from it.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    // The I/O error is part of the message, not a `source`, so that `{:#}` does not print it twice.
    #[error("{file}: cannot read: {cause}")]
    Io { file: String, cause: std::io::Error },
    #[error("{file}: no header row (the file is empty or holds only `#` comments)")]
    NoHeader { file: String },
    #[error(
        "{at}: {value:e} is not a plausible measurement (a finite number below 1e12 in magnitude expected)"
    )]
    Implausible { at: String, value: f64 },
    #[error("{file}:{line}:{column}: quoted field is never closed")]
    UnterminatedQuote {
        file: String,
        line: usize,
        column: usize,
    },
    #[error("{file}:{line}:{column}: text after a closing quote")]
    TextAfterQuote {
        file: String,
        line: usize,
        column: usize,
    },
    #[error("{file}:{line}:{column}: duplicate column `{name}` (first at column {first})")]
    DuplicateColumn {
        file: String,
        line: usize,
        column: usize,
        name: String,
        first: usize,
    },
    #[error(
        "{file}:{line}: {what}; a measurement CSV is comma separated, with `.` as the decimal point and LF \
         or CRLF line ends (export or convert it so)"
    )]
    WrongSeparator {
        file: String,
        line: usize,
        what: String,
    },
    #[error("{file}: {what}; save the file as UTF-8 text (e.g. \"CSV UTF-8\")")]
    NotUtf8 { file: String, what: &'static str },
    #[error("{file}:{line}:{column}: empty column name in the header")]
    EmptyColumnName {
        file: String,
        line: usize,
        column: usize,
    },
    #[error("{file}:{line}:{column}: row has {found} fields but the header has {expected}")]
    RaggedRow {
        file: String,
        line: usize,
        column: usize,
        found: usize,
        expected: usize,
    },
    #[error("{file}:{line}:{column} (column `{name}`): `{text}` is not a number")]
    NotANumber {
        file: String,
        line: usize,
        column: usize,
        name: String,
        text: String,
    },
    #[error("{file}:{line}:{column} (column `{name}`): empty cell where a number is required")]
    EmptyCell {
        file: String,
        line: usize,
        column: usize,
        name: String,
    },
    #[error(
        "{file}:{line}:{column} (column `{name}`): `{text}` is not a timestamp (expected e.g. `2021-06-13 05:42:16`)"
    )]
    BadTimestamp {
        file: String,
        line: usize,
        column: usize,
        name: String,
        text: String,
    },
    #[error(
        "{file}:{line}:{column} (column `{name}`): `{text}` is not a direction (expected +, -, 1, -1, positive or negative)"
    )]
    BadDirection {
        file: String,
        line: usize,
        column: usize,
        name: String,
        text: String,
    },
    #[error("{file}: missing column `{name}`{purpose} (columns: {available})")]
    MissingColumn {
        file: String,
        name: String,
        purpose: String,
        available: String,
    },
    #[error("{file}: no data rows {why}")]
    NoRows { file: String, why: String },
    #[error("{option} `{text}`: {reason}")]
    BadOption {
        option: &'static str,
        text: String,
        reason: String,
    },
    #[error(
        "{file}: column `{column}` holds {count} different values ({values}); one model fits one test of one \
         axis: choose one with --where {column}={example}"
    )]
    SeveralValues {
        file: String,
        column: String,
        count: usize,
        values: String,
        example: String,
    },
    #[error("{file}: column `{name}` has {found} values but the dataset has {expected} rows")]
    LengthMismatch {
        file: String,
        name: String,
        found: usize,
        expected: usize,
    },
}

/// `--where`, `--rename` and `--scale`, parsed.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LoadOptions {
    /// `COL=VALUE`: keep rows whose cell equals VALUE (as text, or as numbers when both read as numbers).
    pub filters: Vec<(String, String)>,
    /// `OLD=NEW`: rename a column before anything else.
    pub renames: Vec<(String, String)>,
    /// `COL=FACTOR`: multiply a numeric column (after renaming).
    pub scales: Vec<(String, f64)>,
}

impl LoadOptions {
    /// Parses the raw option values (`COL=VALUE`, `OLD=NEW`, `COL=FACTOR`).
    pub fn from_args(
        where_: &[String],
        rename: &[String],
        scale: &[String],
    ) -> Result<Self, DataError> {
        let pair = |option: &'static str, s: &str| -> Result<(String, String), DataError> {
            let bad = |reason: &str| DataError::BadOption {
                option,
                text: s.to_string(),
                reason: reason.to_string(),
            };
            let (k, v) = s
                .split_once('=')
                .ok_or_else(|| bad("expected NAME=VALUE"))?;
            let k = k.trim();
            if k.is_empty() {
                return Err(bad("the column name is empty"));
            }
            Ok((k.to_string(), v.trim().to_string()))
        };
        let filters = where_
            .iter()
            .map(|s| pair("--where", s))
            .collect::<Result<Vec<_>, _>>()?;
        let renames = rename
            .iter()
            .map(|s| {
                let (k, v) = pair("--rename", s)?;
                if v.is_empty() {
                    return Err(DataError::BadOption {
                        option: "--rename",
                        text: s.clone(),
                        reason: "the new name is empty".into(),
                    });
                }
                Ok((k, v))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let scales = scale
            .iter()
            .map(|s| {
                let (k, v) = pair("--scale", s)?;
                match v.parse::<f64>() {
                    Ok(f) if f != 0.0 && sanity::plausible_number(f) => Ok((k, f)),
                    _ => Err(DataError::BadOption {
                        option: "--scale",
                        text: s.clone(),
                        reason: format!(
                            "`{v}` is not a finite number (a non-zero factor below 1e12 expected)"
                        ),
                    }),
                }
            })
            .collect::<Result<Vec<_>, _>>()?;
        // One column renamed or scaled twice: which one was meant is a guess (the last must not win silently).
        for (option, keys, given) in [
            (
                "--rename",
                renames.iter().map(|r| &r.0).collect::<Vec<_>>(),
                rename,
            ),
            ("--scale", scales.iter().map(|r| &r.0).collect(), scale),
        ] {
            if let Some(k) = (1..keys.len()).find(|&k| keys[..k].contains(&keys[k])) {
                return Err(DataError::BadOption {
                    option,
                    text: given[k].clone(),
                    reason: format!("column `{}` is named by {option} twice", keys[k]),
                });
            }
        }
        Ok(Self {
            filters,
            renames,
            scales,
        })
    }
}

/// Where the first cell that is not a number sits (row index into the dataset).
#[derive(Debug, Clone, Copy, PartialEq)]
struct BadCell {
    row: usize,
}

#[derive(Debug, Clone)]
struct Column {
    name: String,
    /// 1-based field index in the file; `None` for derived columns (`time_s` from `time`), which are
    /// reported by their index in the dataset.
    file_column: Option<usize>,
    /// The cells as text. A numeric column does not keep its text (half the memory of a large file): it is
    /// written from the values on first use ([`Column::cells`]), in the shortest form that reads back as
    /// the same number (`1.0` → `1`), as a `--scale`d column always was.
    text: std::sync::OnceLock<Cells>,
    values: Result<Vec<f64>, BadCell>,
}

impl Column {
    fn new(name: String, file_column: Option<usize>, text: Cells) -> Self {
        let values = parse_numbers(&text);
        let cells = std::sync::OnceLock::new();
        if values.is_err() {
            let _ = cells.set(text);
        }
        Self {
            name,
            file_column,
            text: cells,
            values,
        }
    }

    fn from_values(name: String, values: Vec<f64>) -> Self {
        Self {
            name,
            file_column: None,
            text: std::sync::OnceLock::new(),
            values: Ok(values),
        }
    }

    /// The text of every cell (see the field's docs).
    fn cells(&self) -> &Cells {
        self.text.get_or_init(|| match &self.values {
            Ok(v) => v.iter().map(|x| format_number(*x)).collect(),
            Err(_) => Cells::default(),
        })
    }
}

fn parse_numbers(text: &Cells) -> Result<Vec<f64>, BadCell> {
    text.iter()
        .enumerate()
        .map(|(row, t)| parse_number(t).ok_or(BadCell { row }))
        .collect()
}

fn parse_number(t: &str) -> Option<f64> {
    let t = t.trim();
    if t.is_empty() { None } else { t.parse().ok() }
}

/// Shortest text that reads back as the same `f64`.
fn format_number(v: f64) -> String {
    format!("{v}")
}

/// The rows of one measurement CSV (see the module docs for the rules).
#[derive(Debug, Clone)]
pub struct Dataset {
    source: String,
    /// Physical line on which each row starts (0 for rows not from a file).
    lines: Vec<usize>,
    columns: Vec<Column>,
}

/// Contract names and their aliases.
const ALIASES: &[(&str, &str)] = &[("run", "cycle"), ("direction", "approach_direction")];

impl Dataset {
    /// Reads and parses `path` (see [`Dataset::from_csv_str`]); messages name the path as given.
    ///
    /// The file is read one record at a time, and rows that a `--where` on an unscaled file column
    /// rejects are dropped as they are read, so memory holds the kept cells (text, end offsets and, for
    /// numeric columns, the values; about 2–3× the kept part of the file), not the file itself.
    pub fn load(path: &Path, opts: &LoadOptions) -> Result<Dataset, DataError> {
        let file = path.display().to_string();
        let io = |cause| DataError::Io {
            file: file.clone(),
            cause,
        };
        let f = std::fs::File::open(path).map_err(io)?;
        let size = f.metadata().map(|m| m.len()).unwrap_or(0);
        let mut reader = std::io::BufReader::with_capacity(1 << 16, f);
        {
            use std::io::BufRead;
            let head = reader.fill_buf().map_err(io)?;
            // UTF-16 (Excel's "Unicode text", some Windows loggers) read as UTF-8 is noise, not CSV.
            if head.starts_with(&[0xff, 0xfe]) || head.starts_with(&[0xfe, 0xff]) {
                return Err(DataError::NotUtf8 {
                    file,
                    what: "the file is UTF-16 text (it starts with a UTF-16 byte-order mark)",
                });
            }
        }
        let mut builder: Option<Builder> = None;
        let result = csv::read_each(reader, &mut |rec| match &mut builder {
            None => {
                builder = Some(Builder::new(&file, rec, opts, size)?);
                Ok(())
            }
            Some(b) => b.push(rec),
        });
        match result {
            Ok(()) => {}
            Err(csv::ReadStop::Io(cause)) => return Err(io(cause)),
            Err(csv::ReadStop::Csv(f)) => return Err(csv_fault(&file, f)),
            Err(csv::ReadStop::Other(e)) => return Err(e),
        }
        builder
            .ok_or_else(|| DataError::NoHeader { file: file.clone() })?
            .finish(opts)
    }

    /// Parses CSV `text`; `source` is the name used in messages.
    pub fn from_csv_str(
        source: &str,
        text: &str,
        opts: &LoadOptions,
    ) -> Result<Dataset, DataError> {
        let file = source.to_string();
        let mut builder: Option<Builder> = None;
        let result = csv::parse_each(text, false, 1, &mut |rec| match &mut builder {
            None => {
                builder = Some(Builder::new(&file, rec, opts, text.len() as u64)?);
                Ok(())
            }
            Some(b) => b.push(rec),
        });
        match result {
            Ok(()) => {}
            Err(csv::ParseStop::Csv(f)) => return Err(csv_fault(&file, f)),
            Err(csv::ParseStop::Other(e)) => return Err(e),
        }
        builder
            .ok_or_else(|| DataError::NoHeader { file: file.clone() })?
            .finish(opts)
    }

    /// A dataset of numeric columns built in memory (e.g. by the twin); `source` names it in messages.
    pub fn from_numeric_columns(
        source: &str,
        columns: Vec<(String, Vec<f64>)>,
    ) -> Result<Dataset, DataError> {
        let n = columns.first().map_or(0, |c| c.1.len());
        let mut ds = Dataset {
            source: source.to_string(),
            lines: vec![0; n],
            columns: Vec::new(),
        };
        for (name, values) in columns {
            ds.add_numeric_column(&name, values)?;
        }
        Ok(ds)
    }

    /// Appends (or replaces) a numeric column.
    pub fn add_numeric_column(&mut self, name: &str, values: Vec<f64>) -> Result<(), DataError> {
        if values.len() != self.n_rows() {
            return Err(DataError::LengthMismatch {
                file: self.source.clone(),
                name: name.to_string(),
                found: values.len(),
                expected: self.n_rows(),
            });
        }
        let col = Column::from_values(name.to_string(), values);
        match self.columns.iter().position(|c| c.name == name) {
            Some(i) => self.columns[i] = col,
            None => self.columns.push(col),
        }
        Ok(())
    }

    /// Appends (or replaces) a text column.
    pub fn add_text_column(&mut self, name: &str, text: Vec<String>) -> Result<(), DataError> {
        if text.len() != self.n_rows() {
            return Err(DataError::LengthMismatch {
                file: self.source.clone(),
                name: name.to_string(),
                found: text.len(),
                expected: self.n_rows(),
            });
        }
        let col = Column::new(name.to_string(), None, text.iter().collect());
        match self.columns.iter().position(|c| c.name == name) {
            Some(i) => self.columns[i] = col,
            None => self.columns.push(col),
        }
        Ok(())
    }

    /// Adds `time_s` (seconds since `first`, the file's first `time` cell, else this dataset's first row)
    /// from a timestamp `time` column.
    fn derive_time_s(&mut self, first: Option<&str>) -> Result<(), DataError> {
        if self.columns.iter().any(|c| c.name == "time_s") {
            return Ok(());
        }
        let Some(ci) = self.columns.iter().position(|c| c.name == "time") else {
            return Ok(());
        };
        let col = &self.columns[ci];
        // A numeric `time` column is not a timestamp column: leave it alone.
        if col.values.is_ok()
            || col
                .cells()
                .iter()
                .next()
                .and_then(timestamp::parse_timestamp)
                .is_none()
        {
            return Ok(());
        }
        let mut secs = Vec::with_capacity(col.cells().len());
        for (row, t) in col.cells().iter().enumerate() {
            match timestamp::parse_timestamp_parts(t) {
                Some(s) => secs.push(s),
                None => {
                    return Err(DataError::BadTimestamp {
                        file: self.source.clone(),
                        line: self.lines[row],
                        column: col.file_column.unwrap_or(ci + 1),
                        name: col.name.clone(),
                        text: t.to_string(),
                    });
                }
            }
        }
        let t0 = first
            .and_then(timestamp::parse_timestamp_parts)
            .unwrap_or_else(|| secs[0]);
        let rel = secs
            .into_iter()
            .map(|s| timestamp::seconds_between(t0, s))
            .collect();
        self.columns.push(Column::from_values("time_s".into(), rel));
        Ok(())
    }

    fn scale_column(&mut self, col: &str, factor: f64) -> Result<(), DataError> {
        let i = self
            .index_of(col)
            .ok_or_else(|| self.missing(col, " (named by --scale)"))?;
        let values: Vec<f64> = self.numeric_at(i)?.iter().map(|v| v * factor).collect();
        let c = &mut self.columns[i];
        c.text = std::sync::OnceLock::new();
        c.values = Ok(values);
        Ok(())
    }

    fn index_of(&self, name: &str) -> Option<usize> {
        if let Some(i) = self.columns.iter().position(|c| c.name == name) {
            return Some(i);
        }
        let other = other_name(name)?;
        self.columns.iter().position(|c| c.name == other)
    }

    fn missing(&self, name: &str, purpose: &str) -> DataError {
        DataError::MissingColumn {
            file: self.source.clone(),
            name: name.to_string(),
            purpose: purpose.to_string(),
            available: self.column_names().join(", "),
        }
    }

    fn column(&self, name: &str, purpose: &str) -> Result<&Column, DataError> {
        self.index_of(name)
            .map(|i| &self.columns[i])
            .ok_or_else(|| self.missing(name, purpose))
    }

    fn numeric_at(&self, i: usize) -> Result<&[f64], DataError> {
        let c = &self.columns[i];
        match &c.values {
            Ok(v) => Ok(v),
            Err(BadCell { row }) => {
                let text = c.cells().get(*row);
                let (file, line, column, name) = (
                    self.source.clone(),
                    self.lines[*row],
                    c.file_column.unwrap_or(i + 1),
                    c.name.clone(),
                );
                Err(if text.trim().is_empty() {
                    DataError::EmptyCell {
                        file,
                        line,
                        column,
                        name,
                    }
                } else {
                    DataError::NotANumber {
                        file,
                        line,
                        column,
                        name,
                        text: text.to_string(),
                    }
                })
            }
        }
    }

    /// The name used in messages (the path as given).
    pub fn source(&self) -> &str {
        &self.source
    }

    pub fn n_rows(&self) -> usize {
        self.lines.len()
    }

    /// Column names in file order (derived `time_s` last).
    pub fn column_names(&self) -> Vec<&str> {
        self.columns.iter().map(|c| c.name.as_str()).collect()
    }

    /// Whether the column (or its alias) exists.
    pub fn has(&self, col: &str) -> bool {
        self.index_of(col).is_some()
    }

    /// For a message about a missing `time_s`: when the file has a `time` column that is not read as
    /// timestamps (numbers, or another date form), says so and how to give seconds; else "".
    pub fn time_hint(&self) -> &'static str {
        if self.has("time") {
            " (its `time` column is not read as timestamps such as `2021-06-13 05:42:16`; if it holds seconds, \
             give it as `time_s` with --rename time=time_s)"
        } else {
            ""
        }
    }

    /// Where a row sits, as `file:line (row N)` (N counted from 1), for messages about a whole row.
    pub fn row_name(&self, row: usize) -> String {
        format!(
            "{}:{} (row {})",
            self.source(),
            self.line_of_row(row),
            row + 1
        )
    }

    /// The physical line of the file on which row `row` starts (0 for rows built in memory).
    pub fn line_of_row(&self, row: usize) -> usize {
        self.lines[row]
    }

    /// Where a cell sits, as `file:line:column (column `name`)`, for messages of other crates.
    pub fn locate(&self, col: &str, row: usize) -> String {
        match self.index_of(col) {
            Some(i) => {
                let c = &self.columns[i];
                format!(
                    "{}:{}:{} (column `{}`)",
                    self.source,
                    self.lines[row],
                    c.file_column.unwrap_or(i + 1),
                    c.name
                )
            }
            None => format!("{}:{}", self.source, self.lines[row]),
        }
    }

    /// The column as numbers; fails naming file, line and column of the first empty or non-numeric cell,
    /// or naming the missing column.
    pub fn numeric(&self, col: &str) -> Result<&[f64], DataError> {
        let i = self.index_of(col).ok_or_else(|| self.missing(col, ""))?;
        self.numeric_at(i)
    }

    /// The column as numbers with empty or non-numeric cells read as NaN (for optional channels);
    /// fails only when the column is missing.
    pub fn numeric_or_nan(&self, col: &str) -> Result<Vec<f64>, DataError> {
        let c = self.column(col, "")?;
        Ok(match &c.values {
            Ok(v) => v.clone(),
            Err(_) => c
                .cells()
                .iter()
                .map(|t| parse_number(t).unwrap_or(f64::NAN))
                .collect(),
        })
    }

    /// Any column as text (numbers as written in the file, or as rescaled).
    pub fn text(&self, col: &str) -> Result<Vec<&str>, DataError> {
        let c = self.column(col, "")?;
        Ok(c.cells().iter().collect())
    }

    /// Names (without the `_degC` suffix) of the temperature sensor columns, in file order.
    pub fn sensors(&self) -> Vec<String> {
        self.columns
            .iter()
            .filter_map(|c| c.name.strip_suffix("_degC"))
            .filter(|s| !s.is_empty())
            .map(str::to_string)
            .collect()
    }

    /// Full names of the `*_um` error-channel columns, in file order (e.g. `deviation_um`, `ch3_um`).
    pub fn error_channels(&self) -> Vec<String> {
        self.columns
            .iter()
            .filter(|c| c.name.len() > 3 && c.name.ends_with("_um"))
            .map(|c| c.name.clone())
            .collect()
    }

    /// Approach direction per row as ±1 (`+`/`-`, `1`/`-1`, `positive`/`negative`, also `pos`/`neg`,
    /// `forward`/`backward`, case-insensitive); `None` without a `direction`/`approach_direction` column.
    pub fn direction(&self) -> Result<Option<Vec<i8>>, DataError> {
        let Some(i) = self.index_of("direction") else {
            return Ok(None);
        };
        let c = &self.columns[i];
        let mut out = Vec::with_capacity(c.cells().len());
        for (row, t) in c.cells().iter().enumerate() {
            let d = parse_direction(t).ok_or_else(|| DataError::BadDirection {
                file: self.source.clone(),
                line: self.lines[row],
                column: c.file_column.unwrap_or(i + 1),
                name: c.name.clone(),
                text: t.to_string(),
            })?;
            out.push(d);
        }
        Ok(Some(out))
    }

    /// Run / cycle labels per row (`run`, alias `cycle`), or `None` without such a column.
    pub fn run(&self) -> Option<Vec<String>> {
        self.index_of("run").map(|i| {
            self.columns[i]
                .cells()
                .iter()
                .map(|t| t.trim().to_string())
                .collect()
        })
    }

    /// Seconds since the start: the `time_s` column, or derived from a `time` timestamp column.
    /// `None` when there is neither, or `time_s` is not numeric (use [`Dataset::numeric`] for the reason).
    pub fn time_s(&self) -> Option<&[f64]> {
        self.numeric("time_s").ok()
    }

    /// The rows where `mask` is true (mask length must equal [`Dataset::n_rows`]).
    pub fn select_rows(&self, mask: &[bool]) -> Dataset {
        assert_eq!(
            mask.len(),
            self.n_rows(),
            "select_rows: mask length differs from the row count"
        );
        let pick = |v: &Cells| -> Cells {
            v.iter()
                .zip(mask)
                .filter(|(_, m)| **m)
                .map(|(t, _)| t)
                .collect()
        };
        Dataset {
            source: self.source.clone(),
            lines: self
                .lines
                .iter()
                .zip(mask)
                .filter(|(_, m)| **m)
                .map(|(l, _)| *l)
                .collect(),
            columns: self
                .columns
                .iter()
                .map(|c| {
                    let (text, values) = match &c.values {
                        Ok(v) => (
                            std::sync::OnceLock::new(),
                            Ok(v.iter()
                                .zip(mask)
                                .filter(|(_, m)| **m)
                                .map(|(x, _)| *x)
                                .collect()),
                        ),
                        Err(_) => {
                            let text = pick(c.cells());
                            let values = parse_numbers(&text);
                            let cell = std::sync::OnceLock::new();
                            let _ = cell.set(text);
                            (cell, values)
                        }
                    };
                    Column {
                        name: c.name.clone(),
                        file_column: c.file_column,
                        text,
                        values,
                    }
                })
                .collect(),
        }
    }

    /// The dataset as CSV (header and rows, RFC 4180 quoting); reading it back gives the same cells.
    pub fn to_csv_string(&self) -> String {
        let mut out = String::new();
        for (i, c) in self.columns.iter().enumerate() {
            if i > 0 {
                out.push(',');
            }
            csv::write_field(&mut out, &c.name);
        }
        out.push('\n');
        for r in 0..self.n_rows() {
            for (i, c) in self.columns.iter().enumerate() {
                if i > 0 {
                    out.push(',');
                }
                csv::write_field(&mut out, &c.cells()[r]);
            }
            out.push('\n');
        }
        out
    }
}

fn csv_fault(file: &str, f: csv::CsvFault) -> DataError {
    match f {
        csv::CsvFault::UnterminatedQuote { line, column } => DataError::UnterminatedQuote {
            file: file.to_string(),
            line,
            column,
        },
        csv::CsvFault::TextAfterQuote { line, column } => DataError::TextAfterQuote {
            file: file.to_string(),
            line,
            column,
        },
    }
}

/// Index of `name` (or its alias) among `names`.
fn resolve(names: &[String], name: &str) -> Option<usize> {
    names.iter().position(|n| n == name).or_else(|| {
        names
            .iter()
            .position(|n| Some(n.as_str()) == other_name(name))
    })
}

/// The other name of a contract column that has an alias (`run` ↔ `cycle`, `direction` ↔
/// `approach_direction`): a lookup by either name finds the column a file has under the other.
fn other_name(name: &str) -> Option<&'static str> {
    ALIASES.iter().find_map(|&(canon, alias)| {
        if name == canon {
            Some(alias)
        } else if name == alias {
            Some(canon)
        } else {
            None
        }
    })
}

/// What is wrong when the header shows another separator than a comma: a one-column header holding `;` (a
/// spreadsheet of a locale with a decimal comma) or tabs, or a header running over bare carriage returns
/// (old Mac line ends make the whole file one line).
fn wrong_separator(names: &[String]) -> Option<String> {
    let short = |t: &str| -> String {
        let t: String = t.chars().take(60).collect();
        t.replace(['\r', '\t'], " ")
    };
    if let Some(n) = names.iter().find(|n| n.contains('\r')) {
        return Some(format!(
            "the header runs over a bare carriage return (`{}`…): the lines end in CR alone (old Mac)",
            short(n)
        ));
    }
    match names {
        [only] if only.contains(';') => Some(format!(
            "the header is one column `{}` holding `;`: the file looks semicolon-separated",
            short(only)
        )),
        [only] if only.contains('\t') => Some(format!(
            "the header is one column `{}` holding tabs: the file looks tab-separated",
            short(only)
        )),
        _ => None,
    }
}

fn parse_direction(t: &str) -> Option<i8> {
    let t = t.trim().to_ascii_lowercase();
    match t.as_str() {
        "+" | "1" | "+1" | "1.0" | "+1.0" | "positive" | "pos" | "forward" | "fwd" => Some(1),
        "-" | "-1" | "-1.0" | "negative" | "neg" | "backward" | "bwd" | "reverse" => Some(-1),
        _ => None,
    }
}

/// A value that `--where COL=VALUE` or `--holdout COL=V1,V2` asks for, as matched against a column's cells:
/// in the approach-direction column any spelling of the same direction (`+` matches `positive` and `1`),
/// else the same number (`2` matches `2.0`), else the same text.
pub(crate) struct WantedCell {
    text: String,
    number: Option<f64>,
    direction: Option<i8>,
}

impl WantedCell {
    pub(crate) fn new(column: &str, text: &str) -> Self {
        let is_direction = ALIASES
            .iter()
            .any(|(a, b)| *a == "direction" && (column == *a || column == *b));
        WantedCell {
            text: text.to_string(),
            number: parse_number(text),
            direction: if is_direction {
                parse_direction(text)
            } else {
                None
            },
        }
    }

    pub(crate) fn matches(&self, cell: &str) -> bool {
        if let (Some(want), Some(got)) = (self.direction, parse_direction(cell)) {
            return want == got;
        }
        match (self.number, parse_number(cell)) {
            (Some(a), Some(b)) => a == b,
            _ => cell.trim() == self.text,
        }
    }
}

/// The shared data directory: `$AXCOMP_SHARED`, else `../shared` next to the workspace root.
/// `workspace_root` is the directory holding the workspace `Cargo.toml`. Returns `None` when it is absent.
pub fn shared_dir(workspace_root: &Path) -> Option<std::path::PathBuf> {
    let dir = match std::env::var_os("AXCOMP_SHARED") {
        Some(d) => std::path::PathBuf::from(d),
        None => workspace_root.join("../shared"),
    };
    dir.is_dir().then_some(dir)
}

/// [`shared_dir`] for a test on real data: `None` (and a `skipped` line) when the directory is absent, a
/// panic when it is absent under CI (`CI` set), where a skipped real-data test would hide a failure.
pub fn shared_dir_for_test(workspace_root: &Path) -> Option<std::path::PathBuf> {
    match shared_dir(workspace_root) {
        Some(d) => Some(d),
        None if std::env::var_os("CI").is_some() => panic!("../shared not found (CI is set)"),
        None => {
            println!("skipped: ../shared not found");
            None
        }
    }
}

#[cfg(test)]
mod tests;
