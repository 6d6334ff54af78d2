//! Laser line measurements read from the contract's CSV, checked line by line.

use axcomp_data::Dataset;

use crate::GeometryError;

/// One reading.
#[derive(Debug, Clone, PartialEq)]
pub struct LineReading {
    /// Axis positions (mm): reflector position minus tool offset.
    pub q: [f64; 3],
    pub tool: [f64; 3],
    /// Unit beam vector.
    pub beam: [f64; 3],
    pub deviation_um: f64,
    /// Index into [`LineData::lines`].
    pub line: usize,
    /// Row in the dataset.
    pub row: usize,
}

/// All readings of a campaign.
#[derive(Debug, Clone, PartialEq)]
pub struct LineData {
    pub readings: Vec<LineReading>,
    /// Line labels, in order of first appearance.
    pub lines: Vec<String>,
}

/// Largest allowed |‖beam‖ − 1|.
pub const BEAM_NORM_TOL: f64 = 1e-3;

fn col_or_zero(ds: &Dataset, name: &str) -> Result<Vec<f64>, GeometryError> {
    if ds.has(name) {
        Ok(ds.numeric(name)?.to_vec())
    } else {
        Ok(vec![0.0; ds.n_rows()])
    }
}

fn finite(ds: &Dataset, name: &str, v: &[f64]) -> Result<(), GeometryError> {
    if let Some(row) = v
        .iter()
        .position(|x| !axcomp_data::sanity::plausible_number(*x))
    {
        return Err(GeometryError::NonFinite {
            at: ds.locate(name, row),
            column: name.to_string(),
        });
    }
    Ok(())
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// The two farthest-apart points of a set (first point → farthest → farthest from that).
fn extent(points: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let far = |from: [f64; 3]| {
        *points
            .iter()
            .max_by(|a, b| norm(sub(**a, from)).total_cmp(&norm(sub(**b, from))))
            .unwrap()
    };
    let a = far(points[0]);
    let b = far(a);
    (a, b)
}

/// Distinct target positions (1 µm resolution).
fn distinct(points: &[[f64; 3]]) -> usize {
    let mut keys: Vec<[i64; 3]> = points
        .iter()
        .map(|p| {
            [
                (p[0] * 1e3).round() as i64,
                (p[1] * 1e3).round() as i64,
                (p[2] * 1e3).round() as i64,
            ]
        })
        .collect();
    keys.sort();
    keys.dedup();
    keys.len()
}

impl LineData {
    /// `rows` (indices into [`LineData::readings`]) in an order that does not depend on the file's row
    /// order: by line label, then axis position, tool offset, beam and deviation (rows equal in all of
    /// these are the same reading, so their order does not matter). The fit sums its normal equations in
    /// this order, so the same measurements give the same model bit for bit whatever order another tool
    /// wrote them in.
    pub fn canonical_order(&self, rows: &[usize]) -> Vec<usize> {
        let cmp3 = |a: [f64; 3], b: [f64; 3]| {
            a[0].total_cmp(&b[0])
                .then(a[1].total_cmp(&b[1]))
                .then(a[2].total_cmp(&b[2]))
        };
        let mut v = rows.to_vec();
        v.sort_by(|&i, &j| {
            let (a, b) = (&self.readings[i], &self.readings[j]);
            self.lines[a.line]
                .cmp(&self.lines[b.line])
                .then_with(|| cmp3(a.q, b.q))
                .then_with(|| cmp3(a.tool, b.tool))
                .then_with(|| cmp3(a.beam, b.beam))
                .then_with(|| a.deviation_um.total_cmp(&b.deviation_um))
        });
        v
    }

    /// Readings (deviation 0) of planned lines, for design and planning.
    pub fn from_specs(specs: &[axcomp_kinematics::LineSpec]) -> LineData {
        let mut readings = Vec::new();
        for (li, l) in specs.iter().enumerate() {
            for r in l.readings() {
                readings.push(LineReading {
                    q: r.q,
                    tool: l.tool,
                    beam: r.beam,
                    deviation_um: 0.0,
                    line: li,
                    row: readings.len(),
                });
            }
        }
        LineData {
            readings,
            lines: specs.iter().map(|l| l.name.clone()).collect(),
        }
    }

    /// Reads the readings of `ds`; `need_deviation` is false for prediction (inputs only). Checks: finite
    /// cells, ≥ 3 distinct targets per line, unit beams, beams along their line's direction.
    pub fn from_dataset(ds: &Dataset, need_deviation: bool) -> Result<LineData, GeometryError> {
        let n = ds.n_rows();
        let mut pos = [Vec::new(), Vec::new(), Vec::new()];
        for (k, c) in ["x_mm", "y_mm", "z_mm"].iter().enumerate() {
            pos[k] = ds.numeric(c)?.to_vec();
            finite(ds, c, &pos[k])?;
        }
        let mut tool = [Vec::new(), Vec::new(), Vec::new()];
        for (k, c) in ["tool_x_mm", "tool_y_mm", "tool_z_mm"].iter().enumerate() {
            tool[k] = col_or_zero(ds, c)?;
            finite(ds, c, &tool[k])?;
        }
        let dev = if need_deviation {
            let d = ds.numeric("deviation_um")?.to_vec();
            finite(ds, "deviation_um", &d)?;
            d
        } else if ds.has("deviation_um") {
            // prediction: the measured column is not needed; blanks are fine
            ds.numeric_or_nan("deviation_um")?
        } else {
            vec![f64::NAN; n]
        };
        let line_text: Vec<String> = if ds.has("line") {
            ds.text("line")?
                .iter()
                .map(|s| s.trim().to_string())
                .collect()
        } else if need_deviation {
            return Err(ds.numeric("line").unwrap_err().into());
        } else {
            vec![String::new(); n]
        };
        let mut lines: Vec<String> = Vec::new();
        let mut line_of = Vec::with_capacity(n);
        for t in &line_text {
            let i = lines.iter().position(|l| l == t).unwrap_or_else(|| {
                lines.push(t.clone());
                lines.len() - 1
            });
            line_of.push(i);
        }
        let has_beam = ["beam_x", "beam_y", "beam_z"].iter().all(|c| ds.has(c));
        let (present, missing): (Vec<&str>, Vec<&str>) = ["beam_x", "beam_y", "beam_z"]
            .iter()
            .partition(|c| ds.has(c));
        if !has_beam && !present.is_empty() {
            // Ignoring a partial beam would silently take the lines' own directions, whose sign may differ
            // from the beam's (and so every reading's).
            return Err(GeometryError::PartialBeam {
                file: ds.source().to_string(),
                present: present.join(", "),
                missing: missing.join(", "),
            });
        }
        let mut beams = vec![[0.0; 3]; n];
        if has_beam {
            let b: Vec<Vec<f64>> = ["beam_x", "beam_y", "beam_z"]
                .iter()
                .map(|c| -> Result<Vec<f64>, GeometryError> {
                    let v = ds.numeric(c)?.to_vec();
                    finite(ds, c, &v)?;
                    Ok(v)
                })
                .collect::<Result<_, _>>()?;
            for (r, beam) in beams.iter_mut().enumerate() {
                *beam = [b[0][r], b[1][r], b[2][r]];
                let nb = norm(*beam);
                if (nb - 1.0).abs() > BEAM_NORM_TOL {
                    return Err(GeometryError::BeamNotUnit {
                        line: lines[line_of[r]].clone(),
                        at: ds.locate("beam_x", r),
                        norm: nb,
                    });
                }
                // within the tolerance (e.g. written with few decimals): a unit vector, as the reading is
                *beam = beam.map(|v| v / nb);
            }
        }
        let q_of = |r: usize| {
            [
                pos[0][r] - tool[0][r],
                pos[1][r] - tool[1][r],
                pos[2][r] - tool[2][r],
            ]
        };
        // per-line checks (and the beam from the line's extent when there is no beam column); rows to be
        // predicted without a line or beam have no beam to check
        let check_lines = need_deviation || has_beam || ds.has("line");
        for (li, name) in lines.iter().enumerate().filter(|_| check_lines) {
            let rows: Vec<usize> = (0..n).filter(|&r| line_of[r] == li).collect();
            let pts: Vec<[f64; 3]> = rows
                .iter()
                .map(|&r| [pos[0][r], pos[1][r], pos[2][r]])
                .collect();
            let targets = distinct(&pts);
            if need_deviation && targets < 3 {
                return Err(GeometryError::TooFewTargets {
                    line: name.clone(),
                    at: ds.locate("line", rows[0]),
                    targets,
                });
            }
            if pts.len() < 2 || targets < 2 {
                if !has_beam {
                    return Err(GeometryError::NoBeam {
                        line: name.clone(),
                        at: ds.locate("line", rows[0]),
                    });
                }
                continue;
            }
            let (a, b) = extent(&pts);
            let d = sub(b, a);
            let dn = norm(d);
            let dir = [d[0] / dn, d[1] / dn, d[2] / dn];
            for &r in &rows {
                // A row's own beam is the direction its reading was taken along (a straightness
                // optic across the line, a tracking interferometer's beam to each point): it is
                // used as given, whatever the line's direction.
                if !has_beam {
                    // direction from the line's first target (file order) to its last one: the far end of
                    // the line as seen from the first (a line measured forward and back ends where it
                    // started; its file-order last row is not its last target)
                    let first = pts[0];
                    let last = *pts
                        .iter()
                        .max_by(|a, b| norm(sub(**a, first)).total_cmp(&norm(sub(**b, first))))
                        .unwrap();
                    let fl = sub(last, first);
                    let fln = norm(fl);
                    beams[r] = if fln > 0.0 {
                        [fl[0] / fln, fl[1] / fln, fl[2] / fln]
                    } else {
                        dir
                    };
                }
            }
        }
        let readings = (0..n)
            .map(|r| LineReading {
                q: q_of(r),
                tool: [tool[0][r], tool[1][r], tool[2][r]],
                beam: beams[r],
                deviation_um: dev[r],
                line: line_of[r],
                row: r,
            })
            .collect();
        Ok(LineData { readings, lines })
    }
}
