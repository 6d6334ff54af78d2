//! `axcomp-kinematics`: how a machine's axes stack and how their geometric errors reach the tool point.
//!
//! # Glossary (signs and conventions; ISO 230-1 names)
//! - **axes** X, Y, Z: three nominally orthogonal linear axes; `q = (x, y, z)` are the axes' own commanded
//!   positions in mm.
//! - **topology** ([`Topology`]): `--work-axes` lists the axes that carry the workpiece from the bed outward,
//!   `--tool-axes` those that carry the tool from the bed outward (default `YX` / `Z`: the table rides on X,
//!   X on Y; the spindle on Z). Every axis appears exactly once.
//! - **tool offset** `t` (mm): the reflector's (or tool tip's) offset from the tool reference point; it is the
//!   Abbe arm of every angular error. The reflector's commanded position is `q + t`.
//! - **error** `e` (µm): reached − commanded position of the tool point *relative to the workpiece*, along the
//!   machine axes (the contract's `e = reached − commanded`).
//! - **components** ([`Component`]): the 21 ISO 230-1 errors. Of axis X, functions of x: `EXX` positioning,
//!   `EYX`, `EZX` straightness, `EAX` roll (about X), `EBX` pitch (about Y), `ECX` yaw (about Z); likewise
//!   of Y and Z. Squareness constants `EC0Y` (Y to X, about Z), `EB0Z` (Z to X, about Y), `EA0Z` (Z to Y,
//!   about X). Linear components in µm, angular ones and squareness in µrad, positive right-handed about
//!   +X, +Y, +Z.
//! - **sign convention**: every component is stated as its effect on the tool point relative to the
//!   workpiece (what a laser between spindle and table sees). For an axis that carries the workpiece this is
//!   the negative of the table's own error motion, so a controller table needs no per-axis sign flips.
//! - **reference point of a component**: linear components are the error at the tool reference point when
//!   only that axis moves (tool offset 0, other axes at 0). Each component is zero at its axis's zero.
//!   Straightness components have zero least-squares slope over the axis's range: the slope between two axes
//!   is the squareness (X defines the x direction, the XY plane is spanned by X and Y).
//! - **lever arm** of an axis's angular error: the vector from that axis's carriage to the tool point along
//!   the chain workpiece → work axes (outermost first) → bed → tool axes (bed outward) → tool offset,
//!   excluding the axis's own travel (absorbed in its straightness): `arm_k = Σ_{links after k} q_j u_j + t`.
//!   For `YX / Z`: `arm_X = (0, y, z) + t`, `arm_Y = (0, 0, z) + t`, `arm_Z = t`. So with the reflector on
//!   the tool reference point (t = 0), `ECY`, `EAZ`, `EBZ`, `ECZ` have no lever arm at all.
//! - **squareness**: Y's direction is `Rz(EC0Y)·ey ≈ (−EC0Y, 1, 0)`, Z's is `Ry(EB0Z)·Rx(EA0Z)·ez ≈
//!   (EB0Z, −EA0Z, 1)`; X's direction is the reference.
//! - **linearised model** ([`sensitivities`]): `e = Σ_k δ_k(q_k) + Σ_k ε_k(q_k) × arm_k + squareness terms`,
//!   with `µrad · mm = 1e-3 µm`. **Exact chain** ([`exact_error`]): the same links as f64 homogeneous
//!   transforms `Trans(q_k u_k) · Trans(δ_k) · Rz·Ry·Rx(ε_k)`; the two agree to second order in the angles
//!   (test `linearised_matches_exact_chain`).
//! - **line** ([`LineSpec`]): a laser measurement line from `start` to `end` (reflector positions) with a
//!   beam along it; `stepwise` lines read after each single-axis step (the seed's step-diagonal readings).
//!
//! Designed so a rotary-axis (five-axis) model can add links of another kind to the same chain.

pub mod lines;
pub mod rotary;

pub use lines::{LineSpec, Reading};
pub use rotary::{FiveAxis, LocationErrors, MachineKind, Pose};

use nalgebra::{Matrix4, Vector3, Vector4};
use serde::{Deserialize, Serialize};

/// Errors of this crate.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum KinematicsError {
    /// A `--work-axes`/`--tool-axes` pair that does not name X, Y and Z exactly once.
    #[error("axis stacking --work-axes {work:?} --tool-axes {tool:?}: {reason}")]
    BadTopology {
        work: String,
        tool: String,
        reason: String,
    },
}

/// One linear axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Hash)]
pub enum Axis {
    X,
    Y,
    Z,
}

impl Axis {
    pub const ALL: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];
    /// 0, 1, 2.
    pub fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }
    pub fn letter(self) -> char {
        ['X', 'Y', 'Z'][self.index()]
    }
    pub fn from_letter(c: char) -> Option<Axis> {
        match c.to_ascii_uppercase() {
            'X' => Some(Axis::X),
            'Y' => Some(Axis::Y),
            'Z' => Some(Axis::Z),
            _ => None,
        }
    }
}

/// What a component is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ComponentKind {
    /// Positioning (direction = own axis) or straightness (another direction), µm, along `dir`.
    Linear { dir: usize },
    /// Rotation about `dir`, µrad.
    Angular { dir: usize },
    /// Squareness constant, µrad.
    Squareness,
}

/// The 21 ISO 230-1 components, in the order of [`Component::ALL`] (of X, of Y, of Z, then squareness).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[allow(clippy::upper_case_acronyms)]
pub enum Component {
    EXX,
    EYX,
    EZX,
    EAX,
    EBX,
    ECX,
    EXY,
    EYY,
    EZY,
    EAY,
    EBY,
    ECY,
    EXZ,
    EYZ,
    EZZ,
    EAZ,
    EBZ,
    ECZ,
    EC0Y,
    EB0Z,
    EA0Z,
}

impl Component {
    pub const ALL: [Component; 21] = [
        Component::EXX,
        Component::EYX,
        Component::EZX,
        Component::EAX,
        Component::EBX,
        Component::ECX,
        Component::EXY,
        Component::EYY,
        Component::EZY,
        Component::EAY,
        Component::EBY,
        Component::ECY,
        Component::EXZ,
        Component::EYZ,
        Component::EZZ,
        Component::EAZ,
        Component::EBZ,
        Component::ECZ,
        Component::EC0Y,
        Component::EB0Z,
        Component::EA0Z,
    ];

    /// Position in [`Component::ALL`].
    pub fn index(self) -> usize {
        Component::ALL.iter().position(|c| *c == self).unwrap()
    }

    /// The ISO 230-1 name (`EXX`, …, `EA0Z`).
    pub fn name(self) -> &'static str {
        [
            "EXX", "EYX", "EZX", "EAX", "EBX", "ECX", "EXY", "EYY", "EZY", "EAY", "EBY", "ECY",
            "EXZ", "EYZ", "EZZ", "EAZ", "EBZ", "ECZ", "EC0Y", "EB0Z", "EA0Z",
        ][self.index()]
    }

    pub fn from_name(s: &str) -> Option<Component> {
        Component::ALL
            .iter()
            .copied()
            .find(|c| c.name().eq_ignore_ascii_case(s.trim()))
    }

    /// The axis whose position the component is a function of (`None` for squareness).
    pub fn axis(self) -> Option<Axis> {
        let i = self.index();
        if i < 18 { Some(Axis::ALL[i / 6]) } else { None }
    }

    pub fn kind(self) -> ComponentKind {
        let i = self.index();
        if i >= 18 {
            ComponentKind::Squareness
        } else if i % 6 < 3 {
            ComponentKind::Linear { dir: i % 6 }
        } else {
            ComponentKind::Angular { dir: i % 6 - 3 }
        }
    }

    /// `"um"` or `"urad"`.
    pub fn unit(self) -> &'static str {
        match self.kind() {
            ComponentKind::Linear { .. } => "um",
            _ => "urad",
        }
    }

    /// Positioning error (linear along its own axis).
    pub fn is_positioning(self) -> bool {
        matches!((self.kind(), self.axis()), (ComponentKind::Linear { dir }, Some(a)) if dir == a.index())
    }

    /// Straightness error (linear across its own axis).
    pub fn is_straightness(self) -> bool {
        matches!(self.kind(), ComponentKind::Linear { .. }) && !self.is_positioning()
    }
}

/// How the axes stack (see the glossary).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Topology {
    /// Axes carrying the workpiece, from the bed outward.
    pub work: Vec<Axis>,
    /// Axes carrying the tool, from the bed outward.
    pub tool: Vec<Axis>,
}

impl Default for Topology {
    fn default() -> Self {
        Topology {
            work: vec![Axis::Y, Axis::X],
            tool: vec![Axis::Z],
        }
    }
}

impl Topology {
    /// From `--work-axes` / `--tool-axes` strings such as `YX` and `Z` (case-insensitive; one may be empty).
    pub fn parse(work: &str, tool: &str) -> Result<Topology, KinematicsError> {
        let bad = |reason: String| KinematicsError::BadTopology {
            work: work.to_string(),
            tool: tool.to_string(),
            reason,
        };
        let letters = |s: &str| -> Result<Vec<Axis>, KinematicsError> {
            s.chars()
                .filter(|c| !c.is_whitespace() && *c != ',')
                .map(|c| Axis::from_letter(c).ok_or_else(|| bad(format!("'{c}' is not X, Y or Z"))))
                .collect()
        };
        let w = letters(work)?;
        let t = letters(tool)?;
        for a in Axis::ALL {
            let n = w.iter().chain(t.iter()).filter(|b| **b == a).count();
            if n != 1 {
                return Err(bad(format!(
                    "axis {} appears {n} times; each of X, Y, Z must appear exactly once",
                    a.letter()
                )));
            }
        }
        Ok(Topology { work: w, tool: t })
    }

    /// `YX/Z` style label.
    pub fn label(&self) -> String {
        let s = |v: &[Axis]| v.iter().map(|a| a.letter()).collect::<String>();
        format!("{}/{}", s(&self.work), s(&self.tool))
    }

    /// The chain from the workpiece to the tool: work axes outermost first, then tool axes bed outward.
    pub fn chain(&self) -> Vec<Axis> {
        self.work
            .iter()
            .rev()
            .chain(self.tool.iter())
            .copied()
            .collect()
    }

    /// Lever arm (mm) of each axis's angular errors, indexed by axis (see the glossary).
    pub fn arms(&self, q: [f64; 3], t: [f64; 3]) -> [[f64; 3]; 3] {
        let chain = self.chain();
        let mut arms = [[0.0; 3]; 3];
        for (k, a) in chain.iter().enumerate() {
            let mut arm = t;
            for b in &chain[k + 1..] {
                arm[b.index()] += q[b.index()];
            }
            arms[a.index()] = arm;
        }
        arms
    }
}

/// Values of the 21 components at one machine position: entry `i` belongs to `Component::ALL[i]`
/// (the 18 functions evaluated at their own axis's position, then the three squareness constants).
pub type ComponentValues = [f64; 21];

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Sensitivity of the tool-point error (µm) to each component at axis positions `q` (mm) and tool offset
/// `t` (mm): `e = Σ_i s[i] · v[i]` in the linearised model (µm per µm, or µm per µrad).
pub fn sensitivities(topo: &Topology, q: [f64; 3], t: [f64; 3]) -> [[f64; 3]; 21] {
    let mut s = [[0.0; 3]; 21];
    let arms = topo.arms(q, t);
    for (i, c) in Component::ALL.iter().enumerate() {
        match c.kind() {
            ComponentKind::Linear { dir } => s[i][dir] = 1.0,
            ComponentKind::Angular { dir } => {
                let mut w = [0.0; 3];
                w[dir] = 1e-3; // µrad · mm → µm
                s[i] = cross(w, arms[c.axis().unwrap().index()]);
            }
            ComponentKind::Squareness => {}
        }
    }
    // Squareness: Y along (−EC0Y, 1, 0), Z along (EB0Z, −EA0Z, 1).
    s[Component::EC0Y.index()] = [-q[1] * 1e-3, 0.0, 0.0];
    s[Component::EB0Z.index()] = [q[2] * 1e-3, 0.0, 0.0];
    s[Component::EA0Z.index()] = [0.0, -q[2] * 1e-3, 0.0];
    s
}

/// Tool-point error (µm) of the linearised model.
pub fn linear_error(topo: &Topology, q: [f64; 3], t: [f64; 3], v: &ComponentValues) -> [f64; 3] {
    let s = sensitivities(topo, q, t);
    let mut e = [0.0; 3];
    for i in 0..21 {
        for d in 0..3 {
            e[d] += s[i][d] * v[i];
        }
    }
    e
}

/// Homogeneous transform of a translation (mm).
pub fn translation(v: [f64; 3]) -> Matrix4<f64> {
    Matrix4::new_translation(&Vector3::new(v[0], v[1], v[2]))
}

/// Homogeneous rotation `Rz(c)·Ry(b)·Rx(a)` (angles in rad).
pub fn rotation_abc(a: f64, b: f64, c: f64) -> Matrix4<f64> {
    let rx = Matrix4::new_rotation(Vector3::new(a, 0.0, 0.0));
    let ry = Matrix4::new_rotation(Vector3::new(0.0, b, 0.0));
    let rz = Matrix4::new_rotation(Vector3::new(0.0, 0.0, c));
    rz * ry * rx
}

/// The actual (squareness-tilted) unit direction of each axis.
pub fn axis_directions(v: &ComponentValues) -> [[f64; 3]; 3] {
    let c0y = v[Component::EC0Y.index()] * 1e-6;
    let b0z = v[Component::EB0Z.index()] * 1e-6;
    let a0z = v[Component::EA0Z.index()] * 1e-6;
    [
        [1.0, 0.0, 0.0],
        [-c0y.sin(), c0y.cos(), 0.0],
        [a0z.cos() * b0z.sin(), -a0z.sin(), a0z.cos() * b0z.cos()],
    ]
}

/// Tool-point error (µm) from the exact f64 homogeneous-transform chain (see the glossary): the tool point
/// `p = Π_k [Trans(q_k u_k) · Trans(δ_k) · Rz·Ry·Rx(ε_k)] · t` in workpiece coordinates, minus `q + t`.
pub fn exact_error(topo: &Topology, q: [f64; 3], t: [f64; 3], v: &ComponentValues) -> [f64; 3] {
    let dirs = axis_directions(v);
    let mut m = Matrix4::identity();
    for a in topo.chain() {
        let k = a.index();
        let base = 6 * k;
        let u = dirs[k];
        let delta = [v[base] * 1e-3, v[base + 1] * 1e-3, v[base + 2] * 1e-3]; // µm → mm
        let (ea, eb, ec) = (v[base + 3] * 1e-6, v[base + 4] * 1e-6, v[base + 5] * 1e-6);
        m = m
            * translation([u[0] * q[k], u[1] * q[k], u[2] * q[k]])
            * translation(delta)
            * rotation_abc(ea, eb, ec);
    }
    let p = m * Vector4::new(t[0], t[1], t[2], 1.0);
    [
        (p[0] - q[0] - t[0]) * 1e3,
        (p[1] - q[1] - t[1]) * 1e3,
        (p[2] - q[2] - t[2]) * 1e3,
    ]
}

/// Dot product.
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn some_values(scale: f64) -> ComponentValues {
        let mut v = [0.0; 21];
        for (i, x) in v.iter_mut().enumerate() {
            // linear ±(2..12) µm, angular ±(5..30) µrad, squareness ±(10..50) µrad
            let s = if i % 2 == 0 { 1.0 } else { -1.0 };
            *x = s * scale * (2.0 + (i as f64 * 7.3) % 10.0) * if i >= 18 { 4.0 } else { 1.0 };
            if i < 18 && i % 6 >= 3 {
                *x *= 2.5;
            }
        }
        v
    }

    /// Reference: the exact f64 HTM chain. Tolerance: the linearisation drops products of two errors
    /// (angle·angle·arm ≲ (50 µrad)²·1000 mm = 2.5e-6 mm, angle·δ ≲ 50e-6·12 µm); 0.01 µm covers both
    /// with margin at 1000 mm arms; at 100× the errors the gap grows quadratically (checked ≥ 10× larger).
    #[test]
    fn linearised_matches_exact_chain() {
        for topo in [
            Topology::default(),
            Topology::parse("", "XYZ").unwrap(),
            Topology::parse("ZYX", "").unwrap(),
            Topology::parse("X", "YZ").unwrap(),
        ] {
            for (q, t) in [
                ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0]),
                ([800.0, 600.0, 500.0], [0.0, 0.0, 0.0]),
                ([300.0, 900.0, 100.0], [50.0, -80.0, 150.0]),
                ([1000.0, 1000.0, 1000.0], [0.0, 0.0, 200.0]),
            ] {
                let v = some_values(1.0);
                let a = linear_error(&topo, q, t, &v);
                let b = exact_error(&topo, q, t, &v);
                for d in 0..3 {
                    assert!(
                        (a[d] - b[d]).abs() < 0.01,
                        "{} q={q:?} t={t:?}: lin {a:?} exact {b:?}",
                        topo.label()
                    );
                }
            }
        }
        // The gap is second order: 100× larger errors give a far larger gap (≥ 10× the small-error one).
        let topo = Topology::default();
        let (q, t) = ([1000.0, 1000.0, 1000.0], [100.0, 100.0, 100.0]);
        let gap = |s: f64| {
            let v = some_values(s);
            let a = linear_error(&topo, q, t, &v);
            let b = exact_error(&topo, q, t, &v);
            (0..3).map(|d| (a[d] - b[d]).abs()).fold(0.0, f64::max) / s
        };
        assert!(gap(100.0) > 10.0 * gap(1.0), "{} {}", gap(100.0), gap(1.0));
    }

    #[test]
    fn seed_arms_for_default_topology() {
        // Seed 000 eq. 9 (XYTZ machine, tool at the origin): X's yaw acts through y, its pitch and Y's
        // pitch through z; ECY and the Z angles have no lever arm.
        let topo = Topology::default();
        let s = sensitivities(&topo, [100.0, 200.0, 300.0], [0.0; 3]);
        assert_eq!(s[Component::ECX.index()], [-0.2, 0.0, 0.0]);
        assert_eq!(s[Component::EBX.index()], [0.3, 0.0, 0.0]);
        assert_eq!(s[Component::EBY.index()], [0.3, 0.0, 0.0]);
        for c in [
            Component::ECY,
            Component::EAZ,
            Component::EBZ,
            Component::ECZ,
        ] {
            assert_eq!(s[c.index()], [0.0; 3], "{}", c.name());
        }
    }

    #[test]
    fn topology_errors_name_the_problem() {
        let e = Topology::parse("YX", "X").unwrap_err().to_string();
        assert!(e.contains("axis X appears 2 times"), "{e}");
        assert!(
            Topology::parse("YQ", "Z")
                .unwrap_err()
                .to_string()
                .contains("'Q'")
        );
    }
}
