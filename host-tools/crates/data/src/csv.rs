//! A small RFC 4180 CSV reader and writer that remembers where every record starts.
//!
//! Terms:
//! - *record*: one logical row; a quoted field may span physical lines, so a record is located by the
//!   physical line (1-based) on which it starts.
//! - *field*: one cell. Quoted fields (`"a, b"`, `"say ""hi"""`) keep their content verbatim; unquoted
//!   fields are trimmed of surrounding spaces and tabs (so `1, 2` reads as `1` and `2`).
//! - *comment*: a line starting with `#` before the header (instrument metadata); skipped.
//!
//! Blank lines are skipped everywhere. A UTF-8 byte-order mark and `\r\n` line ends are accepted, and so
//! is Excel's separator line `sep=,` as the first line.

use std::borrow::Cow;

/// One parsed record: the physical line it starts on and its fields (borrowed from the input unless a
/// quoted field held doubled quotes).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Record<'a> {
    pub line: usize,
    pub fields: Vec<Cow<'a, str>>,
}

/// Why the text is not CSV.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum CsvFault {
    /// A quoted field is never closed; `line` is where the record starts.
    UnterminatedQuote { line: usize, column: usize },
    /// Characters follow a closing quote before the next separator (`"ab"c`).
    TextAfterQuote { line: usize, column: usize },
}

fn is_blank(b: u8) -> bool {
    b == b' ' || b == b'\t'
}

fn trim_blanks(s: &str) -> &str {
    s.trim_matches(|c| c == ' ' || c == '\t')
}

/// Splits `text` into records. The first non-blank, non-comment record is the header.
#[cfg(test)]
pub(crate) fn parse(text: &str) -> Result<Vec<Record<'_>>, CsvFault> {
    let mut records = Vec::new();
    parse_each(text, false, 1, &mut |r| {
        records.push(r);
        Ok(())
    })
    .map_err(|e| match e {
        ParseStop::Csv(f) => f,
        ParseStop::Other(()) => unreachable!(),
    })?;
    Ok(records)
}

/// Why [`parse_each`] stopped: the text is not CSV, or the callback said so.
#[derive(Debug)]
pub(crate) enum ParseStop<E> {
    Csv(CsvFault),
    Other(E),
}

/// Calls `each` with every record of `text` in order, without collecting them. `seen_header`: a header was
/// already read (then `#` lines are data, not comments); `first_line`: the physical line number of the
/// first line of `text`.
pub(crate) fn parse_each<'a, E>(
    text: &'a str,
    seen_header: bool,
    first_line: usize,
    each: &mut dyn FnMut(Record<'a>) -> Result<(), E>,
) -> Result<(), ParseStop<E>> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let b = text.as_bytes();
    let n = b.len();
    let mut i = 0usize;
    let mut line = first_line;
    let mut seen_header = seen_header;
    while i < n {
        // Blank line, or comment line before the header: skip the physical line.
        let eol = b[i..].iter().position(|&c| c == b'\n').map_or(n, |k| i + k);
        let physical = &text[i..eol];
        // Excel's separator hint `sep=,` on the first line is not the header.
        let sep_hint = !seen_header && line == 1 && physical.trim() == "sep=,";
        if physical.trim().is_empty() || (!seen_header && physical.starts_with('#')) || sep_hint {
            i = eol + 1;
            line += 1;
            continue;
        }
        let record_line = line;
        let mut fields: Vec<Cow<'_, str>> = Vec::new();
        loop {
            let mut k = i;
            while k < n && is_blank(b[k]) {
                k += 1;
            }
            if k < n && b[k] == b'"' {
                // Quoted field.
                k += 1;
                let start = k;
                let mut seg = k;
                let mut owned: Option<String> = None;
                loop {
                    if k >= n {
                        return Err(ParseStop::Csv(CsvFault::UnterminatedQuote {
                            line: record_line,
                            column: fields.len() + 1,
                        }));
                    }
                    match b[k] {
                        b'"' if k + 1 < n && b[k + 1] == b'"' => {
                            owned
                                .get_or_insert_with(String::new)
                                .push_str(&text[seg..=k]);
                            k += 2;
                            seg = k;
                        }
                        b'"' => break,
                        b'\n' => {
                            line += 1;
                            k += 1;
                        }
                        _ => k += 1,
                    }
                }
                fields.push(match owned {
                    None => Cow::Borrowed(&text[start..k]),
                    Some(mut s) => {
                        s.push_str(&text[seg..k]);
                        Cow::Owned(s)
                    }
                });
                k += 1; // the closing quote
                while k < n && is_blank(b[k]) {
                    k += 1;
                }
                if k < n && b[k] == b'\r' && (k + 1 == n || b[k + 1] == b'\n') {
                    k += 1;
                }
                if k >= n {
                    i = n;
                    break;
                }
                match b[k] {
                    b',' => i = k + 1,
                    b'\n' => {
                        i = k + 1;
                        line += 1;
                        break;
                    }
                    _ => {
                        return Err(ParseStop::Csv(CsvFault::TextAfterQuote {
                            line: record_line,
                            column: fields.len(),
                        }));
                    }
                }
            } else {
                // Unquoted field: up to the next separator or line end.
                let start = i;
                let mut k = i;
                while k < n && b[k] != b',' && b[k] != b'\n' {
                    k += 1;
                }
                let mut end = k;
                if end > start && b[end - 1] == b'\r' && (k == n || b[k] == b'\n') {
                    end -= 1;
                }
                fields.push(Cow::Borrowed(trim_blanks(&text[start..end])));
                if k >= n {
                    i = n;
                    break;
                }
                i = k + 1;
                if b[k] == b'\n' {
                    line += 1;
                    break;
                }
            }
        }
        seen_header = true;
        each(Record {
            line: record_line,
            fields,
        })
        .map_err(ParseStop::Other)?;
    }
    Ok(())
}

/// Reads CSV from `reader` one record at a time (a record spans physical lines while a quote is open)
/// and calls `each` with it; memory is bounded by the longest record, not the file. Bytes that are not
/// UTF-8 are replaced (U+FFFD), as for text read whole.
pub(crate) fn read_each<R: std::io::BufRead, E>(
    mut reader: R,
    each: &mut dyn FnMut(Record<'_>) -> Result<(), E>,
) -> Result<(), ReadStop<E>> {
    let mut seen_header = false;
    let mut line = 1usize;
    let mut raw: Vec<u8> = Vec::new();
    let mut chunk = String::new();
    let mut first = true;
    loop {
        // One physical line, then more while a quote is open.
        chunk.clear();
        let start_line = line;
        let mut quotes = 0usize;
        loop {
            raw.clear();
            let k = reader.read_until(b'\n', &mut raw).map_err(ReadStop::Io)?;
            if k == 0 {
                break;
            }
            let mut text = String::from_utf8_lossy(&raw);
            if first {
                first = false;
                if let Some(t) = text.strip_prefix('\u{feff}') {
                    text = std::borrow::Cow::Owned(t.to_owned());
                }
            }
            quotes += text.bytes().filter(|&c| c == b'"').count();
            chunk.push_str(&text);
            line += 1;
            if quotes % 2 == 0 {
                break;
            }
        }
        if chunk.is_empty() {
            return Ok(());
        }
        let mut got_record = false;
        parse_each(&chunk, seen_header, start_line, &mut |r| {
            got_record = true;
            each(r)
        })
        .map_err(|e| match e {
            ParseStop::Csv(f) => ReadStop::Csv(f),
            ParseStop::Other(o) => ReadStop::Other(o),
        })?;
        seen_header |= got_record;
    }
}

/// Why [`read_each`] stopped.
#[derive(Debug)]
pub(crate) enum ReadStop<E> {
    Io(std::io::Error),
    Csv(CsvFault),
    Other(E),
}

/// Writes one field, quoting it when reading it back would otherwise change it.
pub(crate) fn write_field(out: &mut String, field: &str) {
    let needs_quotes = field.contains([',', '"', '\n', '\r'])
        || field.starts_with([' ', '\t', '#'])
        || field.ends_with([' ', '\t']);
    if needs_quotes {
        out.push('"');
        for c in field.chars() {
            if c == '"' {
                out.push('"');
            }
            out.push(c);
        }
        out.push('"');
    } else {
        out.push_str(field);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fields(text: &str) -> Vec<Vec<String>> {
        parse(text)
            .unwrap()
            .into_iter()
            .map(|r| r.fields.into_iter().map(String::from).collect())
            .collect()
    }

    #[test]
    fn quoted_fields_keep_commas_and_doubled_quotes() {
        let r = fields("a,b,c\n1,\"x, y\",\"say \"\"hi\"\"\"\n");
        assert_eq!(r[1], vec!["1", "x, y", "say \"hi\""]);
    }

    #[test]
    fn comments_before_header_and_blank_lines_are_skipped_with_line_numbers_kept() {
        let recs = parse("# meta\n## more\n\na,b\n\n1,2\r\n3,4").unwrap();
        let lines: Vec<usize> = recs.iter().map(|r| r.line).collect();
        assert_eq!(lines, vec![4, 6, 7]);
        assert_eq!(recs[2].fields, vec!["3", "4"]);
    }

    #[test]
    fn hash_after_header_is_data() {
        let r = fields("a\n#1\n");
        assert_eq!(r[1], vec!["#1"]);
    }

    #[test]
    fn multiline_quoted_field_counts_lines() {
        let recs = parse("a,b\n\"x\ny\",2\n3,4\n").unwrap();
        assert_eq!(recs[1].fields, vec!["x\ny", "2"]);
        assert_eq!(recs[2].line, 4);
    }

    #[test]
    fn unterminated_quote_is_reported_where_the_record_starts() {
        assert_eq!(
            parse("a,b\n1,\"open\n2,3\n"),
            Err(CsvFault::UnterminatedQuote { line: 2, column: 2 })
        );
    }

    #[test]
    fn text_after_closing_quote_is_an_error() {
        assert_eq!(
            parse("a,b\n\"x\"y,2\n"),
            Err(CsvFault::TextAfterQuote { line: 2, column: 1 })
        );
    }

    #[test]
    fn unquoted_fields_are_trimmed_and_empty_fields_kept() {
        let r = fields("Time [s], Fx [N]\n 1 ,,\n");
        assert_eq!(r[0], vec!["Time [s]", "Fx [N]"]);
        assert_eq!(r[1], vec!["1", "", ""]);
    }

    #[test]
    fn bom_is_ignored() {
        assert_eq!(fields("\u{feff}a\n1\n")[0], vec!["a"]);
    }

    #[test]
    fn writer_round_trips_awkward_fields() {
        let awkward = ["plain", "a,b", "q\"q", " lead", "#x", "", "multi\nline"];
        let mut line = String::new();
        for (i, f) in awkward.iter().enumerate() {
            if i > 0 {
                line.push(',');
            }
            write_field(&mut line, f);
        }
        let text = format!("h1,h2,h3,h4,h5,h6,h7\n{line}\n");
        assert_eq!(fields(&text)[1], awkward.to_vec());
    }
}
