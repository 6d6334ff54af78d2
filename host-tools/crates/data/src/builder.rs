//! Building a [`Dataset`] from the records of one CSV: the header's columns, the `--where` filters
//! that can be applied while reading, the first `time` cell; at the end the columns, `time_s`,
//! `--scale` and the remaining `--where` filters.

use super::*;

/// Collects the records of one CSV into columns (see [`Dataset::load`]).
pub(crate) struct Builder {
    file: String,
    names: Vec<String>,
    lines: Vec<usize>,
    cells: Vec<Cells>,
    /// `--where` filters applied while reading: (column index, wanted value).
    early: Vec<(usize, WantedCell)>,
    /// The first data row's `time` cell (before any filter): `time_s` is relative to it.
    first_time: Option<String>,
    time_col: Option<usize>,
    /// Size of the input in bytes, for the capacity estimate after the first rows.
    size: u64,
    records: usize,
    bytes_read: u64,
}

impl Builder {
    pub(crate) fn new(
        file: &str,
        header: csv::Record<'_>,
        opts: &LoadOptions,
        size: u64,
    ) -> Result<Self, DataError> {
        let file = file.to_string();
        let mut names: Vec<String> = header.fields.into_iter().map(String::from).collect();
        // A separator at the end of every line (some loggers and spreadsheets write one) makes an empty
        // last header field: it names no column, so it is dropped (the rows' empty last fields with it).
        while names.len() > 1 && names.last().is_some_and(|n| n.is_empty()) {
            names.pop();
        }
        if let Some(what) = wrong_separator(&names) {
            return Err(DataError::WrongSeparator {
                file,
                line: header.line,
                what,
            });
        }
        // `--rename` before anything else (so a rename can also fix a duplicate).
        for (old, new) in &opts.renames {
            let Some(i) = names.iter().position(|n| n == old) else {
                return Err(DataError::MissingColumn {
                    file,
                    name: old.clone(),
                    purpose: " (named by --rename)".into(),
                    available: names.join(", "),
                });
            };
            names[i] = new.clone();
        }
        for (i, name) in names.iter().enumerate() {
            if name.is_empty() {
                return Err(DataError::EmptyColumnName {
                    file,
                    line: header.line,
                    column: i + 1,
                });
            }
            if let Some(first) = names[..i].iter().position(|n| n == name) {
                return Err(DataError::DuplicateColumn {
                    file,
                    line: header.line,
                    column: i + 1,
                    name: name.clone(),
                    first: first + 1,
                });
            }
        }
        let scaled: Vec<usize> = opts
            .scales
            .iter()
            .filter_map(|(c, _)| resolve(&names, c))
            .collect();
        let early = opts
            .filters
            .iter()
            .filter_map(|(c, v)| {
                let i = resolve(&names, c)?;
                (!scaled.contains(&i)).then(|| (i, WantedCell::new(&names[i], v)))
            })
            .collect();
        let time_col = if names.iter().any(|n| n == "time_s") {
            None
        } else {
            names.iter().position(|n| n == "time")
        };
        let width = names.len();
        Ok(Builder {
            file,
            names,
            lines: Vec::new(),
            cells: (0..width).map(|_| Cells::default()).collect(),
            early,
            first_time: None,
            time_col,
            size,
            records: 0,
            bytes_read: 0,
        })
    }

    pub(crate) fn push(&mut self, rec: csv::Record<'_>) -> Result<(), DataError> {
        let width = self.names.len();
        // Fields past the header's last column are accepted when empty (a trailing separator).
        let extra_blank =
            rec.fields.len() > width && rec.fields[width..].iter().all(|f| f.is_empty());
        if rec.fields.len() != width && !extra_blank {
            return Err(DataError::RaggedRow {
                file: self.file.clone(),
                line: rec.line,
                column: rec.fields.len().min(width) + 1,
                found: rec.fields.len(),
                expected: width,
            });
        }
        if self.records == 0 {
            if let Some(t) = self.time_col {
                self.first_time = Some(rec.fields[t].to_string());
            }
        }
        self.records += 1;
        let row_bytes: usize = rec.fields.iter().map(|f| f.len() + 1).sum();
        self.bytes_read += row_bytes as u64;
        if self.records == 1024 {
            self.reserve();
        }
        let keep = self
            .early
            .iter()
            .all(|(c, want)| want.matches(&rec.fields[*c]));
        if !keep {
            return Ok(());
        }
        for (c, f) in rec.fields.iter().take(width).enumerate() {
            if !self.cells[c].fits(f.len()) {
                return Err(DataError::BadOption {
                    option: "--data",
                    text: self.file.clone(),
                    reason: format!(
                        "column `{}` holds more than 4 GiB of text; split the file or select rows with --where",
                        self.names[c]
                    ),
                });
            }
            self.cells[c].push(f);
        }
        self.lines.push(rec.line);
        Ok(())
    }

    /// After the first rows: reserve room for the rows the file size suggests (when no early filter
    /// drops rows), so the columns do not grow by doubling (which can hold twice the memory).
    fn reserve(&mut self) {
        if !self.early.is_empty() || self.bytes_read == 0 {
            return;
        }
        let per_row = self.bytes_read as f64 / self.records as f64;
        let rows = ((self.size as f64 / per_row) * 1.05) as usize;
        let extra = rows.saturating_sub(self.lines.len());
        self.lines.reserve(extra);
        for c in &mut self.cells {
            let per_cell = c.bytes() as f64 / c.len().max(1) as f64;
            c.reserve(extra, (extra as f64 * per_cell * 1.05) as usize);
        }
    }

    pub(crate) fn finish(self, opts: &LoadOptions) -> Result<Dataset, DataError> {
        let file = self.file;
        if self.records == 0 {
            return Err(DataError::NoRows {
                file,
                why: "after the header".into(),
            });
        }
        let columns = self
            .names
            .into_iter()
            .zip(self.cells)
            .enumerate()
            .map(|(i, (name, mut text))| {
                text.shrink_to_fit();
                Column::new(name, Some(i + 1), text)
            })
            .collect();
        let mut lines = self.lines;
        lines.shrink_to_fit();
        let mut ds = Dataset {
            source: file,
            lines,
            columns,
        };
        ds.derive_time_s(self.first_time.as_deref())?;
        for (col, factor) in &opts.scales {
            ds.scale_column(col, *factor)?;
        }
        if !opts.filters.is_empty() {
            let mut keep = vec![true; ds.n_rows()];
            for (col, value) in &opts.filters {
                let c = ds.column(col, " (named by --where)")?;
                let want = WantedCell::new(col, value);
                for (k, t) in keep.iter_mut().zip(c.cells().iter()) {
                    *k &= want.matches(t);
                }
            }
            if keep.iter().any(|k| !k) || ds.n_rows() == 0 {
                ds = ds.select_rows(&keep);
            }
            if ds.n_rows() == 0 {
                let what: Vec<String> = opts
                    .filters
                    .iter()
                    .map(|(c, v)| format!("{c}={v}"))
                    .collect();
                return Err(DataError::NoRows {
                    file: ds.source,
                    why: format!("match --where {}", what.join(" --where ")),
                });
            }
        }
        Ok(ds)
    }
}
