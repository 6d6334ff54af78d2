//! Laser measurement lines: where the reflector goes and along which beam it is read.
//!
//! A [`LineSpec`] runs from `start` to `end` in the axes' own positions (mm); the reflector sits at
//! `q + tool` (the tool offset is the Abbe arm). The beam points from start to end. A *step-wise* line (the
//! seed's step-diagonal readings) moves one axis at a time between targets, X then Y then Z, and is read
//! after each single-axis step, so its readings lie on a staircase around the diagonal.

use serde::{Deserialize, Serialize};

/// One measurement line.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LineSpec {
    pub name: String,
    /// Axis positions (mm) at the first target.
    pub start: [f64; 3],
    /// Axis positions (mm) at the last target.
    pub end: [f64; 3],
    /// Targets including both ends (≥ 2).
    pub targets: usize,
    /// Read after each single-axis step between targets.
    pub stepwise: bool,
    /// Reflector offset from the tool reference point (mm).
    pub tool: [f64; 3],
    /// A tracking interferometer's station (mm, workpiece frame): each reading is taken along the beam from
    /// the station to the reflector instead of along the line.
    pub station: Option<[f64; 3]>,
}

/// One reading point of a line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reading {
    /// Axis positions (mm).
    pub q: [f64; 3],
    /// Reflector position (mm) = q + tool.
    pub pos: [f64; 3],
    /// Unit beam vector.
    pub beam: [f64; 3],
}

impl LineSpec {
    pub fn new(name: &str, start: [f64; 3], end: [f64; 3], targets: usize) -> LineSpec {
        LineSpec {
            name: name.to_string(),
            start,
            end,
            targets,
            stepwise: false,
            tool: [0.0; 3],
            station: None,
        }
    }

    /// Read each point along the beam from `station` (a tracking interferometer).
    pub fn from_station(mut self, station: [f64; 3]) -> LineSpec {
        self.station = Some(station);
        self
    }

    pub fn stepwise(mut self) -> LineSpec {
        self.stepwise = true;
        self
    }

    pub fn with_tool(mut self, tool: [f64; 3]) -> LineSpec {
        self.tool = tool;
        self
    }

    /// Unit vector from start to end (zero for a degenerate line).
    pub fn beam(&self) -> [f64; 3] {
        let d = [
            self.end[0] - self.start[0],
            self.end[1] - self.start[1],
            self.end[2] - self.start[2],
        ];
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if n == 0.0 {
            return [0.0; 3];
        }
        [d[0] / n, d[1] / n, d[2] / n]
    }

    /// The reading points in measuring order (start to end).
    pub fn readings(&self) -> Vec<Reading> {
        let beam = self.beam();
        let n = self.targets.max(2);
        let at = |i: usize| -> [f64; 3] {
            let f = i as f64 / (n - 1) as f64;
            [
                self.start[0] + f * (self.end[0] - self.start[0]),
                self.start[1] + f * (self.end[1] - self.start[1]),
                self.start[2] + f * (self.end[2] - self.start[2]),
            ]
        };
        let mut qs = vec![at(0)];
        for i in 1..n {
            let (a, b) = (at(i - 1), at(i));
            if self.stepwise {
                let mut p = a;
                for k in 0..3 {
                    if (b[k] - a[k]).abs() > 1e-12 {
                        p[k] = b[k];
                        qs.push(p);
                    }
                }
                // the last sub-step lands on the target exactly
                if let Some(last) = qs.last_mut() {
                    *last = b;
                }
            } else {
                qs.push(b);
            }
        }
        qs.into_iter()
            .map(|q| {
                let pos = [
                    q[0] + self.tool[0],
                    q[1] + self.tool[1],
                    q[2] + self.tool[2],
                ];
                let beam = match self.station {
                    None => beam,
                    Some(s) => {
                        let d = [pos[0] - s[0], pos[1] - s[1], pos[2] - s[2]];
                        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                        if n > 0.0 { d.map(|v| v / n) } else { beam }
                    }
                };
                Reading { q, pos, beam }
            })
            .collect()
    }
}

/// A line along `axis` (0, 1, 2) over its stroke, with the other axes at `at` (mm).
pub fn axis_line(
    name: &str,
    axis: usize,
    stroke: [f64; 3],
    at: [f64; 3],
    targets: usize,
) -> LineSpec {
    let mut s = at;
    let mut e = at;
    s[axis] = 0.0;
    e[axis] = stroke[axis];
    LineSpec::new(name, s, e, targets)
}

/// The four body diagonals of the box `[0, stroke]`.
pub fn body_diagonals(stroke: [f64; 3], targets: usize, stepwise: bool) -> Vec<LineSpec> {
    let [x, y, z] = stroke;
    let lines = [
        ([0.0, 0.0, 0.0], [x, y, z]),
        ([x, 0.0, 0.0], [0.0, y, z]),
        ([0.0, y, 0.0], [x, 0.0, z]),
        ([x, y, 0.0], [0.0, 0.0, z]),
    ];
    lines
        .iter()
        .enumerate()
        .map(|(i, (s, e))| {
            let l = LineSpec::new(&format!("BD{}", i + 1), *s, *e, targets);
            if stepwise { l.stepwise() } else { l }
        })
        .collect()
}

/// The two face diagonals of the plane spanned by axes `a` and `b` at the third axis's position `at`.
pub fn face_diagonals(
    stroke: [f64; 3],
    a: usize,
    b: usize,
    at: f64,
    targets: usize,
    stepwise: bool,
) -> Vec<LineSpec> {
    let c = 3 - a - b;
    let mut out = Vec::new();
    for (k, (sa, ea)) in [(0.0, stroke[a]), (stroke[a], 0.0)].iter().enumerate() {
        let mut s = [0.0; 3];
        let mut e = [0.0; 3];
        s[a] = *sa;
        e[a] = *ea;
        s[b] = 0.0;
        e[b] = stroke[b];
        s[c] = at;
        e[c] = at;
        let name = format!("FD{}{}{}", ['X', 'Y', 'Z'][a], ['X', 'Y', 'Z'][b], k + 1);
        let l = LineSpec::new(&name, s, e, targets);
        out.push(if stepwise { l.stepwise() } else { l });
    }
    out
}

/// Seed 000's seven lines: 1 along X (y = z = 0); 2–3 the XY face diagonals at z = 0 read step-wise
/// (3 from (0,0) to (xn,yn), 2 from (xn,0) to (0,yn)); 4–7 the four body diagonals read step-wise.
pub fn seven_line(stroke: [f64; 3], targets: usize) -> Vec<LineSpec> {
    let [x, y, _] = stroke;
    let mut v = vec![
        axis_line("L1", 0, stroke, [0.0; 3], targets),
        LineSpec::new("L2", [x, 0.0, 0.0], [0.0, y, 0.0], targets).stepwise(),
        LineSpec::new("L3", [0.0, 0.0, 0.0], [x, y, 0.0], targets).stepwise(),
    ];
    for (i, mut l) in body_diagonals(stroke, targets, true)
        .into_iter()
        .enumerate()
    {
        l.name = format!("L{}", i + 4);
        v.push(l);
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stepwise_diagonal_reads_after_each_axis_step() {
        let l = LineSpec::new("d", [0.0; 3], [10.0, 20.0, 30.0], 3).stepwise();
        let r = l.readings();
        // start + 2 intervals × 3 single-axis steps
        assert_eq!(r.len(), 7);
        assert_eq!(r[1].q, [5.0, 0.0, 0.0]);
        assert_eq!(r[2].q, [5.0, 10.0, 0.0]);
        assert_eq!(r[3].q, [5.0, 10.0, 15.0]);
        assert_eq!(r[6].q, [10.0, 20.0, 30.0]);
        let b = l.beam();
        assert!((b[0] * b[0] + b[1] * b[1] + b[2] * b[2] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn seven_lines_as_in_the_seed() {
        let v = seven_line([500.0, 400.0, 300.0], 11);
        assert_eq!(v.len(), 7);
        assert!(!v[0].stepwise && v[1..].iter().all(|l| l.stepwise));
        assert_eq!(v[0].beam(), [1.0, 0.0, 0.0]);
    }
}
