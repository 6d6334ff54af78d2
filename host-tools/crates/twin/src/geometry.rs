//! The three-axis machine twin for geometric errors: 21 ISO 230-1 components with known truth, laser line
//! plans, noise and slow drift; writes the contract's laser line CSV (`x_mm, y_mm, z_mm, line,
//! deviation_um, beam_*, tool_*_mm, run, direction, time_s`).
//!
//! Glossary (conventions of `axcomp-kinematics`):
//! - **truth**: each of the 18 component functions is a smooth curve `g(u) = c1·u + c2·u² + c3·u³ +
//!   c4·sin(2πku + φ)`, `u = q / stroke`, k ∈ [0.5, 1), made zero at the axis's zero (straightness also with zero
//!   least-squares slope over the stroke, the squareness convention) and scaled to a drawn peak: positioning
//!   5–20 µm, straightness 2–10 µm, angular 5–30 µrad; squareness 10–50 µrad, random signs.
//! - **reading**: `(exact HTM error at the reading) · beam + drift · beam + noise`, µm; the reflector is at
//!   the axes' positions plus the line's tool offset.
//! - **drift**: a position-independent error growing linearly in time (µm/h per machine axis), the slow
//!   thermal drift of a long campaign; 0 unless set.

use axcomp_kinematics::lines::{self, LineSpec};
use axcomp_kinematics::{Component, ComponentKind, ComponentValues, Topology, dot, exact_error};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

/// Volumetric error magnitude of a compensated run ([`GeometryTwin::compensated_volume`]): before (no
/// compensation) and after, max and rms over the grid's points, µm.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct VolumetricResidual {
    pub points: usize,
    pub before_max_um: f64,
    pub before_rms_um: f64,
    pub after_max_um: f64,
    pub after_rms_um: f64,
}

/// One smooth truth function of a component over its axis (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct TruthCurve {
    pub stroke_mm: f64,
    pub c: [f64; 4],
    pub k: f64,
    pub phase: f64,
    /// Slope removed (straightness convention), per unit u.
    pub slope: f64,
    pub scale: f64,
}

impl TruthCurve {
    fn g(&self, u: f64) -> f64 {
        self.c[0] * u
            + self.c[1] * u * u
            + self.c[2] * u * u * u
            + self.c[3] * (std::f64::consts::TAU * self.k * u + self.phase).sin()
    }

    /// Value at axis position `q` (mm).
    pub fn at(&self, q: f64) -> f64 {
        let u = q / self.stroke_mm;
        self.scale * (self.g(u) - self.g(0.0) - self.slope * u)
    }

    fn random<R: Rng>(rng: &mut R, stroke_mm: f64, peak: f64, straightness: bool) -> TruthCurve {
        let mut t = TruthCurve {
            stroke_mm,
            c: [
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(0.0..0.5),
            ],
            k: rng.gen_range(0.5..1.0),
            phase: rng.gen_range(0.0..std::f64::consts::TAU),
            slope: 0.0,
            scale: 1.0,
        };
        let n = 401;
        let us: Vec<f64> = (0..n).map(|i| i as f64 / (n - 1) as f64).collect();
        if straightness {
            // least-squares slope of g over [0, 1]
            let gs: Vec<f64> = us.iter().map(|&u| t.g(u)).collect();
            let mu = 0.5;
            let mg = gs.iter().sum::<f64>() / n as f64;
            let sxy: f64 = us.iter().zip(&gs).map(|(u, g)| (u - mu) * (g - mg)).sum();
            let sxx: f64 = us.iter().map(|u| (u - mu) * (u - mu)).sum();
            t.slope = sxy / sxx;
        }
        let max = us
            .iter()
            .map(|&u| t.at(u * stroke_mm).abs())
            .fold(0.0, f64::max);
        if max > 0.0 {
            t.scale = peak / max;
        }
        t
    }
}

/// The three-axis machine with known geometric errors.
#[derive(Debug, Clone, PartialEq)]
pub struct GeometryTwin {
    pub stroke_mm: [f64; 3],
    pub topology: Topology,
    /// The 18 component functions, in `Component::ALL` order.
    pub curves: Vec<TruthCurve>,
    /// EC0Y, EB0Z, EA0Z (µrad).
    pub squareness_urad: [f64; 3],
    /// Reading noise σ (µm).
    pub noise_um: f64,
    /// Drift rate per machine axis (µm/h).
    pub drift_um_per_h: [f64; 3],
    /// Dwell per reading (s), the seed's 5 s.
    pub dwell_s: f64,
}

impl GeometryTwin {
    /// A machine with random components in the specified ranges, reproducible from `seed`.
    pub fn random(stroke_mm: [f64; 3], topology: Topology, seed: u64) -> GeometryTwin {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x006e_6f6d_6574_7279);
        let mut curves = Vec::with_capacity(18);
        for c in &Component::ALL[..18] {
            let axis = c.axis().unwrap().index();
            let (lo, hi, straight) = if c.is_positioning() {
                (5.0, 20.0, false)
            } else if c.is_straightness() {
                (2.0, 10.0, true)
            } else {
                (5.0, 30.0, false)
            };
            let peak = rng.gen_range(lo..hi);
            curves.push(TruthCurve::random(
                &mut rng,
                stroke_mm[axis],
                peak,
                straight,
            ));
        }
        let mut sq = [0.0; 3];
        for s in sq.iter_mut() {
            let sign = if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
            *s = sign * rng.gen_range(10.0..50.0);
        }
        GeometryTwin {
            stroke_mm,
            topology,
            curves,
            squareness_urad: sq,
            noise_um: 0.5,
            drift_um_per_h: [0.0; 3],
            dwell_s: 5.0,
        }
    }

    /// Truth of one component at its axis's position `pos_mm` (squareness: the constant).
    pub fn component(&self, c: Component, pos_mm: f64) -> f64 {
        match c.kind() {
            ComponentKind::Squareness => self.squareness_urad[c.index() - 18],
            _ => self.curves[c.index()].at(pos_mm),
        }
    }

    /// All 21 components at axis positions `q`.
    pub fn values_at(&self, q: [f64; 3]) -> ComponentValues {
        let mut v = [0.0; 21];
        for (i, c) in Component::ALL.iter().enumerate() {
            v[i] = match c.axis() {
                Some(a) => self.component(*c, q[a.index()]),
                None => self.component(*c, 0.0),
            };
        }
        v
    }

    /// True tool-point error (µm, exact HTM chain) at axis positions `q` with tool offset `t`.
    pub fn error(&self, q: [f64; 3], t: [f64; 3]) -> [f64; 3] {
        exact_error(&self.topology, q, t, &self.values_at(q))
    }

    /// A compensated run over the volume: an `n`³ grid of axis positions in `[lo, hi]` (mm), tool offset
    /// `t` (mm). Each position q is commanded through `controller` (q → the corrected command, mm: the
    /// controller with its compensation, e.g. the core's geometric stage and its rounding to counts); the
    /// axes go where commanded and the tool point lands, relative to the workpiece, at the corrected command
    /// plus the truth error there (exact HTM chain). Residual = landed − q; before = the truth error at q.
    pub fn compensated_volume(
        &self,
        lo: [f64; 3],
        hi: [f64; 3],
        n: usize,
        t: [f64; 3],
        mut controller: impl FnMut([f64; 3]) -> [f64; 3],
    ) -> VolumetricResidual {
        let n = n.max(2);
        let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let mut r = VolumetricResidual::default();
        let (mut sb, mut sa) = (0.0, 0.0);
        for i in 0..n {
            for j in 0..n {
                for k in 0..n {
                    let f =
                        |a: usize, s: usize| lo[a] + (hi[a] - lo[a]) * s as f64 / (n - 1) as f64;
                    let q = [f(0, i), f(1, j), f(2, k)];
                    let before = norm(self.error(q, t));
                    let c = controller(q);
                    let e = self.error(c, t);
                    let landed: [f64; 3] = std::array::from_fn(|d| c[d] + e[d] * 1e-3);
                    let after = norm(std::array::from_fn(|d| (landed[d] - q[d]) * 1e3));
                    r.before_max_um = r.before_max_um.max(before);
                    r.after_max_um = r.after_max_um.max(after);
                    sb += before * before;
                    sa += after * after;
                    r.points += 1;
                }
            }
        }
        r.before_rms_um = (sb / r.points as f64).sqrt();
        r.after_rms_um = (sa / r.points as f64).sqrt();
        r
    }

    /// Measures `lines`, each `runs` times (run 1 = all lines, then run 2, …), with noise and drift from
    /// `seed`.
    pub fn measure(&self, lines: &[LineSpec], runs: usize, seed: u64) -> LineCampaign {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let noise = Normal::new(0.0, self.noise_um.max(0.0)).expect("finite σ");
        let mut rows = Vec::new();
        let mut time = 0.0;
        for run in 1..=runs.max(1) {
            for l in lines {
                for r in l.readings() {
                    let e = self.error(r.q, l.tool);
                    let h = time / 3600.0;
                    let drift = [
                        self.drift_um_per_h[0] * h,
                        self.drift_um_per_h[1] * h,
                        self.drift_um_per_h[2] * h,
                    ];
                    let truth = dot(e, r.beam);
                    let dev = truth + dot(drift, r.beam) + noise.sample(&mut rng);
                    rows.push(LineRow {
                        pos_mm: r.pos,
                        line: l.name.clone(),
                        deviation_um: dev,
                        truth_um: truth,
                        beam: r.beam,
                        tool_mm: l.tool,
                        run,
                        time_s: time,
                    });
                    time += self.dwell_s;
                }
            }
        }
        LineCampaign { rows }
    }
}

/// One reading.
#[derive(Debug, Clone, PartialEq)]
pub struct LineRow {
    pub pos_mm: [f64; 3],
    pub line: String,
    pub deviation_um: f64,
    /// Noise- and drift-free reading.
    pub truth_um: f64,
    pub beam: [f64; 3],
    pub tool_mm: [f64; 3],
    pub run: usize,
    pub time_s: f64,
}

/// The readings of a line campaign.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LineCampaign {
    pub rows: Vec<LineRow>,
}

impl LineCampaign {
    /// The contract's laser line CSV.
    pub fn to_csv_string(&self) -> String {
        let mut s = String::from(
            "x_mm,y_mm,z_mm,line,deviation_um,beam_x,beam_y,beam_z,tool_x_mm,tool_y_mm,tool_z_mm,run,direction,time_s\n",
        );
        for r in &self.rows {
            s.push_str(&format!(
                "{:.4},{:.4},{:.4},{},{:.5},{:.9},{:.9},{:.9},{},{},{},{},+,{:.1}\n",
                r.pos_mm[0],
                r.pos_mm[1],
                r.pos_mm[2],
                r.line,
                r.deviation_um,
                r.beam[0],
                r.beam[1],
                r.beam[2],
                r.tool_mm[0],
                r.tool_mm[1],
                r.tool_mm[2],
                r.run,
                r.time_s
            ));
        }
        s
    }
}

/// A tracking interferometer's campaign (a LaserTRACER-like multilateration): points along lines through
/// the volume — each axis at its four corner offsets and through the centre — every line read from each of
/// four stations on the table, 150 mm outside the stroke's corners at Z = 0, each point along its own beam
/// from the station. Line names say which line and station (`X1@S2`).
fn point_cloud(stroke: [f64; 3], targets: usize) -> Vec<LineSpec> {
    let [x, y, _] = stroke;
    let m = 150.0;
    let stations = [
        [-m, -m, 0.0],
        [x + m, -m, 0.0],
        [-m, y + m, 0.0],
        [x + m, y + m, 0.0],
    ];
    let mut v = Vec::new();
    for (a, others) in [(0usize, [1usize, 2]), (1, [0, 2]), (2, [0, 1])] {
        let offsets = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.5, 0.5)];
        for (i, (p, q)) in offsets.iter().enumerate() {
            let mut at = [0.0; 3];
            at[others[0]] = p * stroke[others[0]];
            at[others[1]] = q * stroke[others[1]];
            for (k, s) in stations.iter().enumerate() {
                let n = format!("{}{}@S{}", ['X', 'Y', 'Z'][a], i + 1, k + 1);
                v.push(lines::axis_line(&n, a, stroke, at, targets).from_station(*s));
            }
        }
    }
    v
}

/// Named line plans over `stroke` with `targets` per line: `seven-line` (seed 000), `step-diagonal` (the
/// four body diagonals read step-wise), `axis-lines` (each axis at the four corner offsets of the other
/// two), `face-diagonals` (XY, XZ, YZ at the lower faces), `tool-offsets` (each axis line with the
/// reflector 100 mm off along each other direction, and a body diagonal with (100, 100, 100) mm), `complete` (axis lines at offsets + step-wise body diagonals +
/// two tool-offset diagonals: every component separable), `point-cloud` (points read along their own beams
/// from four stations, see [`point_cloud`]). `None` for an unknown name.
pub fn plan_by_name(name: &str, stroke: [f64; 3], targets: usize) -> Option<Vec<LineSpec>> {
    let [x, y, z] = stroke;
    let axis_lines = || {
        let mut v = Vec::new();
        for (a, others) in [(0usize, [1usize, 2]), (1, [0, 2]), (2, [0, 1])] {
            for (i, (p, q)) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
                .iter()
                .enumerate()
            {
                let mut at = [0.0; 3];
                at[others[0]] = p * stroke[others[0]];
                at[others[1]] = q * stroke[others[1]];
                let n = format!("{}{}", ['X', 'Y', 'Z'][a], i + 1);
                v.push(lines::axis_line(&n, a, stroke, at, targets));
            }
        }
        v
    };
    let tool_lines = || {
        // each axis line with the reflector 100 mm off along each of the other two directions
        let off = 100.0;
        let mut v = Vec::new();
        for a in 0..3 {
            for b in (0..3).filter(|b| *b != a) {
                let mut t = [0.0; 3];
                t[b] = off;
                let n = format!("T{}{}", ['X', 'Y', 'Z'][a], ['x', 'y', 'z'][b]);
                v.push(lines::axis_line(&n, a, stroke, [0.0; 3], targets).with_tool(t));
            }
        }
        v.push(LineSpec::new("TD", [0.0; 3], [x, y, z], targets).with_tool([off, off, off]));
        v
    };
    Some(match name {
        "seven-line" => lines::seven_line(stroke, targets),
        "step-diagonal" => lines::body_diagonals(stroke, targets, true),
        "axis-lines" => axis_lines(),
        "face-diagonals" => {
            let mut v = lines::face_diagonals(stroke, 0, 1, 0.0, targets, false);
            v.extend(lines::face_diagonals(stroke, 0, 2, 0.0, targets, false));
            v.extend(lines::face_diagonals(stroke, 1, 2, 0.0, targets, false));
            v
        }
        "tool-offsets" => tool_lines(),
        "point-cloud" => point_cloud(stroke, targets),
        "complete" => {
            let mut v = axis_lines();
            v.extend(lines::body_diagonals(stroke, targets, true));
            v.extend(tool_lines());
            v
        }
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truth_in_the_issue_ranges_and_zero_at_zero() {
        let twin = GeometryTwin::random([600.0, 500.0, 400.0], Topology::default(), 3);
        for c in Component::ALL {
            let (lo, hi) = if c.is_positioning() {
                (5.0, 20.0)
            } else if c.is_straightness() {
                (2.0, 10.0)
            } else if c.index() >= 18 {
                (10.0, 50.0)
            } else {
                (5.0, 30.0)
            };
            let stroke = c.axis().map(|a| twin.stroke_mm[a.index()]).unwrap_or(1.0);
            let peak = (0..=100)
                .map(|i| twin.component(c, stroke * i as f64 / 100.0).abs())
                .fold(0.0, f64::max);
            assert!(
                peak >= lo - 1e-9 && peak <= hi + 1e-9,
                "{} peak {peak}",
                c.name()
            );
            if c.index() < 18 {
                assert!(twin.component(c, 0.0).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn campaign_csv_has_the_contract_columns() {
        let twin = GeometryTwin::random([600.0, 500.0, 400.0], Topology::default(), 1);
        let lines = plan_by_name("seven-line", twin.stroke_mm, 6).unwrap();
        let c = twin.measure(&lines, 2, 7);
        let csv = c.to_csv_string();
        assert!(csv.starts_with("x_mm,y_mm,z_mm,line,deviation_um,beam_x,beam_y,beam_z,"));
        // line 1: 6 targets; 2–3: 1 + 5·2; 4–7: 1 + 5·3; two runs
        assert_eq!(c.rows.len(), 2 * (6 + 2 * 11 + 4 * 16));
    }
}
