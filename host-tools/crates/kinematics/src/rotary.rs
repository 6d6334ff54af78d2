//! Five-axis kinematics: the rotary axes' location errors (ISO 230-7) seen by an R-test.
//!
//! # Glossary (signs and conventions)
//! - **machine frame**: origin at the nominal intersection of the two rotary axes; `p = (x, y, z)` mm is the
//!   commanded tool-point position (tool length included), as in the contract's R-test CSV.
//! - **kinds** ([`MachineKind`]): `ac-trunnion` (C table on an A trunnion tilting about an axis parallel to
//!   X), `bc-trunnion` (C table on a B trunnion tilting about Y), `bc-head` (the spindle head carries B,
//!   tilting about Y, riding on C, turning about Z; `pivot_mm` = L, distance from the B axis to the tool
//!   point; the tool points along −Z at B = C = 0).
//! - **nominal sphere**: for a trunnion the sphere's position in the table frame (the frame the C table
//!   carries, equal to the machine frame at A|B = C = 0): `s = Rc(c)ᵀ·Rt(t)ᵀ·p`; for a head the sphere's
//!   machine position `s = p`. Each pose gives its own `s`, so campaigns with several sphere positions work.
//! - **location errors** ([`LocationErrors`], µm and µrad): the actual average line of each rotary axis.
//!   C: passes through `(EX0C, EY0C, 0)` with direction `Ry(EB0C)·Rx(EA0C)·ez ≈ (EB0C, −EA0C, 1)`, stated in
//!   the frame the tilt axis carries (the machine frame at tilt 0) for trunnions, relative to the pivot for
//!   the head. A: through `(0, EY0A, EZ0A)`, direction `Rz(EC0A)·Ry(EB0A)·ex ≈ (1, EC0A, −EB0A)`.
//!   B: through `(EX0B, 0, EZ0B)`, direction `Rz(EC0B)·Rx(EA0B)·ey ≈ (−EC0B, 1, EA0B)`.
//!   A rotary axis turns points about its actual line: `v ↦ p + R_w(θ)(v − p)`, so it moves nothing at
//!   θ = 0 and an offset along the axis's own direction has no effect at all (it is not a parameter).
//!   Linear squareness as in the crate root: Y along `Rz(EC0Y)·ey`, Z along `Ry(EB0Z)·Rx(EA0Z)·ez`.
//! - **set-up offsets** (nuisance, µm, [`SetupOffsets`]): where the sphere actually sits relative to its
//!   nominal position, in the table frame (trunnions) or the machine frame (head); and where the R-test head's
//!   zero (or the probe's calibrated tip) sits relative to the commanded tool point (tool length and radial
//!   offset errors, R-test zeroing): machine frame for trunnions, spindle frame for the head.
//! - **displacement** `d` (µm): the sphere centre relative to the R-test head (tool point), along machine X,
//!   Y, Z: `d = S_actual − T_actual`. A probe route gives the same: fitted centre − commanded tool point.
//! - **exact model** ([`FiveAxis::displacement`]): f64 homogeneous transforms
//!   `Trans(p)·Q·R(θ)·Qᵀ·Trans(−p)` per rotary axis. **Sensitivity** ([`FiveAxis::sensitivity`]): the
//!   analytic first-order derivative at zero errors, `d ≈ Σ_k J_k θ_k` (test
//!   `sensitivity_matches_finite_differences`).

use nalgebra::{Matrix3, Matrix4, Rotation3, Vector3, Vector4};
use serde::{Deserialize, Serialize};

/// Largest commanded tilt angle (A or B) accepted, degrees (either sign).
pub const TILT_LIMIT_DEG: f64 = 150.0;
/// Largest commanded C angle accepted, degrees (either sign; two turns each way).
pub const C_LIMIT_DEG: f64 = 720.0;

/// Number of location-error parameters (the seed's 11).
pub const N_LOCATION: usize = 11;
/// Number of sphere set-up offsets per set-up.
pub const N_SETUP: usize = 6;

/// Set-up offsets (µm): the sphere's `[dx, dy, dz]` (table frame for trunnions, machine frame for the head),
/// then the R-test head's (or probe's) `[dx, dy, dz]` relative to the tool point (machine frame for trunnions,
/// the spindle frame that turns with C and B for the head).
pub type SetupOffsets = [f64; N_SETUP];

/// The kinematic structure of a five-axis machine.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MachineKind {
    /// C table on an A trunnion (A about X).
    AcTrunnion,
    /// C table on a B trunnion (B about Y).
    BcTrunnion,
    /// Spindle head: B (about Y) riding on C (about Z).
    BcHead,
}

impl MachineKind {
    /// Contract name (`ac-trunnion`, ...).
    pub fn name(self) -> &'static str {
        match self {
            MachineKind::AcTrunnion => "ac-trunnion",
            MachineKind::BcTrunnion => "bc-trunnion",
            MachineKind::BcHead => "bc-head",
        }
    }

    /// Parses a contract name.
    pub fn parse(s: &str) -> Option<MachineKind> {
        match s.trim() {
            "ac-trunnion" => Some(MachineKind::AcTrunnion),
            "bc-trunnion" => Some(MachineKind::BcTrunnion),
            "bc-head" => Some(MachineKind::BcHead),
            _ => None,
        }
    }

    /// The tilting axis letter: `a` or `b`.
    pub fn tilt_letter(self) -> char {
        match self {
            MachineKind::AcTrunnion => 'a',
            _ => 'b',
        }
    }

    /// ISO 230-7 names of the 11 location errors, in parameter order.
    pub fn location_names(self) -> [&'static str; N_LOCATION] {
        let tilt = match self {
            MachineKind::AcTrunnion => ["EY0A", "EZ0A", "EB0A", "EC0A"],
            _ => ["EX0B", "EZ0B", "EA0B", "EC0B"],
        };
        [
            "EX0C", "EY0C", "EA0C", "EB0C", tilt[0], tilt[1], tilt[2], tilt[3], "EA0Z", "EB0Z",
            "EC0Y",
        ]
    }
}

/// Unit of location-error parameter `k` (in [`MachineKind::location_names`] order).
pub fn location_unit(k: usize) -> &'static str {
    match k {
        0 | 1 | 4 | 5 => "um",
        _ => "urad",
    }
}

/// The 11 location errors, in [`MachineKind::location_names`] order: C offsets (µm) and tilts (µrad), tilt
/// axis offsets (µm) and tilts (µrad), linear squareness `EA0Z`, `EB0Z`, `EC0Y` (µrad).
pub type LocationErrors = [f64; N_LOCATION];

/// One commanded pose.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Commanded tool-point position, mm.
    pub p_mm: [f64; 3],
    /// Commanded tilt angle (A or B), degrees.
    pub tilt_deg: f64,
    /// Commanded C angle, degrees.
    pub c_deg: f64,
}

/// A five-axis machine's nominal kinematics.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FiveAxis {
    pub kind: MachineKind,
    /// `bc-head`: distance from the B axis to the tool point, mm (ignored for trunnions).
    pub pivot_mm: f64,
}

fn v3(a: [f64; 3]) -> Vector3<f64> {
    Vector3::new(a[0], a[1], a[2])
}

fn arr(v: Vector3<f64>) -> [f64; 3] {
    [v[0], v[1], v[2]]
}

fn rot(axis: usize, angle: f64) -> Matrix3<f64> {
    let mut w = Vector3::zeros();
    w[axis] = angle;
    *Rotation3::new(w).matrix()
}

fn htm_rot(r: Matrix3<f64>) -> Matrix4<f64> {
    let mut m = Matrix4::identity();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    m
}

fn htm_trans(p: Vector3<f64>) -> Matrix4<f64> {
    Matrix4::new_translation(&p)
}

/// Exact HTM of a rotation by `angle` about the line through `p` (mm) with direction `q·e_axis`:
/// `Trans(p)·Q·R_axis(angle)·Qᵀ·Trans(−p)`.
pub fn rotary_htm(p: Vector3<f64>, q: Matrix3<f64>, axis: usize, angle: f64) -> Matrix4<f64> {
    htm_trans(p) * htm_rot(q) * htm_rot(rot(axis, angle)) * htm_rot(q.transpose()) * htm_trans(-p)
}

fn apply(m: &Matrix4<f64>, v: Vector3<f64>) -> Vector3<f64> {
    let r = m * Vector4::new(v[0], v[1], v[2], 1.0);
    Vector3::new(r[0], r[1], r[2])
}

/// First-order change of `R_w(θ)·v` about a line through the origin when the line moves by `dp` and its
/// direction turns by the small rotation vector `phi`: `(I − R)·dp + φ × (R·v) − R·(φ × v)`.
fn delta_rotary(
    r: &Matrix3<f64>,
    v: Vector3<f64>,
    dp: Vector3<f64>,
    phi: Vector3<f64>,
) -> Vector3<f64> {
    (Matrix3::identity() - r) * dp + phi.cross(&(r * v)) - r * phi.cross(&v)
}

impl FiveAxis {
    /// A machine of `kind`; `pivot_mm` is used by `bc-head` only.
    pub fn new(kind: MachineKind, pivot_mm: f64) -> FiveAxis {
        FiveAxis { kind, pivot_mm }
    }

    fn tilt_axis(&self) -> usize {
        match self.kind {
            MachineKind::AcTrunnion => 0,
            _ => 1,
        }
    }

    /// Nominal rotation of the rotary chain: trunnion `Rt(t)·Rc(c)`, head `Rc(c)·Rb(b)`.
    fn nominal_rotations(&self, pose: &Pose) -> (Matrix3<f64>, Matrix3<f64>) {
        (
            rot(self.tilt_axis(), pose.tilt_deg.to_radians()),
            rot(2, pose.c_deg.to_radians()),
        )
    }

    /// Nominal orientation of the spindle (and of a probe in it) relative to the machine frame at `pose`:
    /// the head's `Rc(c)·Rb(b)`; the identity for a trunnion, whose spindle does not turn. A vector `v`
    /// given in the spindle frame is `R·v` in the machine frame.
    pub fn spindle_rotation(&self, pose: &Pose) -> Matrix3<f64> {
        match self.kind {
            MachineKind::BcHead => {
                let (rb, rc) = self.nominal_rotations(pose);
                rc * rb
            }
            _ => Matrix3::identity(),
        }
    }

    /// The nominal sphere position (mm) that the commanded pose aims at (see the glossary).
    pub fn nominal_sphere(&self, pose: &Pose) -> [f64; 3] {
        let (rt, rc) = self.nominal_rotations(pose);
        match self.kind {
            MachineKind::BcHead => pose.p_mm,
            _ => arr(rc.transpose() * rt.transpose() * v3(pose.p_mm)),
        }
    }

    /// The tool vector from the pivot at B = C = 0 (head only), mm.
    fn tool_vector(&self) -> Vector3<f64> {
        Vector3::new(0.0, 0.0, -self.pivot_mm)
    }

    /// Linear axes' positions (mm) for a pose: the tool point for trunnions, the pivot for the head.
    pub fn linear_positions(&self, pose: &Pose) -> [f64; 3] {
        match self.kind {
            MachineKind::BcHead => {
                let (rb, rc) = self.nominal_rotations(pose);
                arr(v3(pose.p_mm) - rc * rb * self.tool_vector())
            }
            _ => pose.p_mm,
        }
    }

    fn tilt_geometry(&self, le: &LocationErrors) -> (Vector3<f64>, Matrix3<f64>) {
        let u = 1e-6;
        match self.kind {
            MachineKind::AcTrunnion => (
                Vector3::new(0.0, le[4] * 1e-3, le[5] * 1e-3),
                rot(2, le[7] * u) * rot(1, le[6] * u),
            ),
            _ => (
                Vector3::new(le[4] * 1e-3, 0.0, le[5] * 1e-3),
                rot(2, le[7] * u) * rot(0, le[6] * u),
            ),
        }
    }

    fn c_geometry(&self, le: &LocationErrors) -> (Vector3<f64>, Matrix3<f64>) {
        (
            Vector3::new(le[0] * 1e-3, le[1] * 1e-3, 0.0),
            rot(1, le[3] * 1e-6) * rot(0, le[2] * 1e-6),
        )
    }

    /// Actual displacement of linear-axis positions `q` (mm) from squareness: `y·u_y + z·u_z − (0, y, z)`.
    fn linear_actual(&self, q: [f64; 3], le: &LocationErrors) -> Vector3<f64> {
        let u = 1e-6;
        let uy = rot(2, le[10] * u) * Vector3::y();
        let uz = rot(1, le[9] * u) * rot(0, le[8] * u) * Vector3::z();
        Vector3::x() * q[0] + uy * q[1] + uz * q[2]
    }

    /// Exact displacement `d = S − T` (µm) of the sphere centre relative to the tool point for `pose`, with
    /// location errors `le` and the sphere sitting `setup_um` away from its nominal position (`sphere_mm`,
    /// e.g. [`FiveAxis::nominal_sphere`]).
    pub fn displacement_at(
        &self,
        pose: &Pose,
        sphere_mm: [f64; 3],
        le: &LocationErrors,
        setup_um: SetupOffsets,
    ) -> [f64; 3] {
        let t = pose.tilt_deg.to_radians();
        let c = pose.c_deg.to_radians();
        let (pt, qt) = self.tilt_geometry(le);
        let (pc, qc) = self.c_geometry(le);
        let m_tilt = rotary_htm(pt, qt, self.tilt_axis(), t);
        let m_c = rotary_htm(pc, qc, 2, c);
        let s = v3(sphere_mm) + Vector3::new(setup_um[0], setup_um[1], setup_um[2]) * 1e-3;
        let head = Vector3::new(setup_um[3], setup_um[4], setup_um[5]) * 1e-3;
        let d = match self.kind {
            MachineKind::BcHead => {
                let q = self.linear_positions(pose);
                let m = m_c * m_tilt;
                let tool = self.linear_actual(q, le) + apply(&m, self.tool_vector() + head);
                s - tool
            }
            _ => {
                let sphere = apply(&(m_tilt * m_c), s);
                sphere - self.linear_actual(pose.p_mm, le) - head
            }
        };
        arr(d * 1e3)
    }

    /// Exact displacement (µm) with the nominal sphere taken from the pose itself.
    pub fn displacement(
        &self,
        pose: &Pose,
        le: &LocationErrors,
        setup_um: SetupOffsets,
    ) -> [f64; 3] {
        self.displacement_at(pose, self.nominal_sphere(pose), le, setup_um)
    }

    /// Sensitivity (first-order, at zero errors) of `d` (µm) to the 11 location errors (per µm / µrad) and
    /// then to the 6 set-up offsets (per µm): `J[k]` is the column of parameter `k`.
    pub fn sensitivity(&self, pose: &Pose) -> [[f64; 3]; N_LOCATION + N_SETUP] {
        let (rt, rc) = self.nominal_rotations(pose);
        let s = v3(self.nominal_sphere(pose));
        let um = 1e-3; // µm in mm
        let ur = 1e-6; // µrad in rad
        let e = |i: usize| {
            let mut v = Vector3::zeros();
            v[i] = 1.0;
            v
        };
        let zero = Vector3::zeros();
        // (dp, phi) of each rotary parameter, per unit (mm, rad).
        let c_params: [(Vector3<f64>, Vector3<f64>); 4] = [
            (e(0) * um, zero),
            (e(1) * um, zero),
            (zero, e(0) * ur),
            (zero, e(1) * ur),
        ];
        let tilt_params: [(Vector3<f64>, Vector3<f64>); 4] = match self.kind {
            MachineKind::AcTrunnion => [
                (e(1) * um, zero),
                (e(2) * um, zero),
                (zero, e(1) * ur),
                (zero, e(2) * ur),
            ],
            _ => [
                (e(0) * um, zero),
                (e(2) * um, zero),
                (zero, e(0) * ur),
                (zero, e(2) * ur),
            ],
        };
        let q = v3(self.linear_positions(pose));
        // −δT of squareness per µrad: EA0Z, EB0Z, EC0Y.
        let square = [
            Vector3::new(0.0, q[2], 0.0) * ur,
            Vector3::new(-q[2], 0.0, 0.0) * ur,
            Vector3::new(q[1], 0.0, 0.0) * ur,
        ];
        let mut j = [[0.0; 3]; N_LOCATION + N_SETUP];
        let mut put = |k: usize, v: Vector3<f64>| j[k] = arr(v * 1e3);
        match self.kind {
            MachineKind::BcHead => {
                let tool = self.tool_vector();
                let v_c = rt * tool; // the tool vector after B, seen by C
                for (k, (dp, phi)) in c_params.iter().enumerate() {
                    put(k, -delta_rotary(&rc, v_c, *dp, *phi));
                }
                for (k, (dp, phi)) in tilt_params.iter().enumerate() {
                    put(4 + k, -(rc * delta_rotary(&rt, tool, *dp, *phi)));
                }
                for (k, v) in square.iter().enumerate() {
                    put(8 + k, *v);
                }
                for i in 0..3 {
                    put(N_LOCATION + i, e(i) * um);
                    put(N_LOCATION + 3 + i, -(rc * rt * e(i)) * um);
                }
            }
            _ => {
                for (k, (dp, phi)) in c_params.iter().enumerate() {
                    put(k, rt * delta_rotary(&rc, s, *dp, *phi));
                }
                for (k, (dp, phi)) in tilt_params.iter().enumerate() {
                    put(4 + k, delta_rotary(&rt, rc * s, *dp, *phi));
                }
                for (k, v) in square.iter().enumerate() {
                    put(8 + k, *v);
                }
                for i in 0..3 {
                    put(N_LOCATION + i, rt * rc * e(i) * um);
                    put(N_LOCATION + 3 + i, -e(i) * um);
                }
            }
        }
        j
    }

    /// The linearised displacement `Σ J_k θ_k` (µm).
    pub fn displacement_linear(
        &self,
        pose: &Pose,
        le: &LocationErrors,
        setup_um: SetupOffsets,
    ) -> [f64; 3] {
        let j = self.sensitivity(pose);
        let mut d = [0.0; 3];
        for (k, col) in j.iter().enumerate() {
            let th = if k < N_LOCATION {
                le[k]
            } else {
                setup_um[k - N_LOCATION]
            };
            for i in 0..3 {
                d[i] += col[i] * th;
            }
        }
        d
    }
}

/// The commanded pose that puts the tool point on a sphere at `sphere_mm` (table frame for trunnions,
/// machine frame for the head) at angles `tilt_deg`, `c_deg`.
pub fn pose_on_sphere(machine: &FiveAxis, sphere_mm: [f64; 3], tilt_deg: f64, c_deg: f64) -> Pose {
    let p = match machine.kind {
        MachineKind::BcHead => sphere_mm,
        _ => {
            let (rt, rc) = machine.nominal_rotations(&Pose {
                p_mm: [0.0; 3],
                tilt_deg,
                c_deg,
            });
            arr(rt * rc * v3(sphere_mm))
        }
    };
    Pose {
        p_mm: p,
        tilt_deg,
        c_deg,
    }
}

/// A K4-type simultaneous five-axis path (ISO 10791-6): C makes a full turn in `n` equal steps
/// (`c = 360°·k/n`) while the tilt axis swings `0 → tilt_max_deg → 0` as `tilt_max·(1 − cos c)/2`, and X, Y,
/// Z follow the sphere.
pub fn k4_path(machine: &FiveAxis, sphere_mm: [f64; 3], tilt_max_deg: f64, n: usize) -> Vec<Pose> {
    (0..n)
        .map(|k| {
            let c = 360.0 * k as f64 / n as f64;
            let t = tilt_max_deg * (1.0 - c.to_radians().cos()) / 2.0;
            pose_on_sphere(machine, sphere_mm, t, c)
        })
        .collect()
}

/// A C circle at a fixed tilt: `n` equal steps of C over a full turn, X, Y, Z following the sphere.
pub fn c_circle(machine: &FiveAxis, sphere_mm: [f64; 3], tilt_deg: f64, n: usize) -> Vec<Pose> {
    (0..n)
        .map(|k| pose_on_sphere(machine, sphere_mm, tilt_deg, 360.0 * k as f64 / n as f64))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn poses() -> Vec<Pose> {
        let mut v = Vec::new();
        for k in 0..12 {
            let c = k as f64 * 30.0;
            let t = -60.0 * (1.0 - c.to_radians().cos()) / 2.0;
            v.push(Pose {
                p_mm: [0.0, 0.0, 0.0],
                tilt_deg: t,
                c_deg: c,
            });
        }
        v
    }

    fn with_sphere(m: &FiveAxis, pose: Pose, s: [f64; 3]) -> Pose {
        let t = pose.tilt_deg.to_radians();
        let c = pose.c_deg.to_radians();
        let p = match m.kind {
            MachineKind::BcHead => s,
            _ => {
                let ax = if m.kind == MachineKind::AcTrunnion {
                    0
                } else {
                    1
                };
                arr(rot(ax, t) * rot(2, c) * v3(s))
            }
        };
        Pose { p_mm: p, ..pose }
    }

    /// Every machine kind (head pivot 250 mm) with every test pose, the sphere at `sphere_mm`.
    fn machine_poses(sphere_mm: [f64; 3]) -> Vec<(MachineKind, FiveAxis, Pose)> {
        let mut out = Vec::new();
        for kind in [
            MachineKind::AcTrunnion,
            MachineKind::BcTrunnion,
            MachineKind::BcHead,
        ] {
            let m = FiveAxis::new(kind, 250.0);
            for pose in poses() {
                out.push((kind, m, with_sphere(&m, pose, sphere_mm)));
            }
        }
        out
    }

    /// Reference: central finite differences of the exact HTM model (step 1e-3 µm / µrad); tolerance
    /// 1e-6 µm per unit parameter (the truncation and rounding errors are far below).
    #[test]
    fn sensitivity_matches_finite_differences() {
        for (kind, m, pose) in machine_poses([120.0, -40.0, 80.0]) {
            let j = m.sensitivity(&pose);
            for k in 0..N_LOCATION + N_SETUP {
                let h = 1e-3;
                let mut lp = [0.0; N_LOCATION];
                let mut lm = [0.0; N_LOCATION];
                let mut sp = [0.0; N_SETUP];
                let mut sm = [0.0; N_SETUP];
                if k < N_LOCATION {
                    lp[k] = h;
                    lm[k] = -h;
                } else {
                    sp[k - N_LOCATION] = h;
                    sm[k - N_LOCATION] = -h;
                }
                let dp = m.displacement(&pose, &lp, sp);
                let dm = m.displacement(&pose, &lm, sm);
                for i in 0..3 {
                    let fd = (dp[i] - dm[i]) / (2.0 * h);
                    assert!(
                        (fd - j[k][i]).abs() < 1e-6,
                        "{kind:?} param {} comp {i}: analytic {} fd {fd}",
                        k,
                        j[k][i]
                    );
                }
            }
        }
    }

    /// Reference: the exact model; with errors up to 50 µm / 90 µrad the linearised model must agree to
    /// second order: (Σ|θ_angles|)²·lever ≈ (4e-4)²·300 mm ≈ 5e-5 mm → tolerance 0.05 µm.
    #[test]
    fn linearised_matches_exact_for_realistic_errors() {
        let le = [
            30.0, -20.0, 80.0, -60.0, 40.0, -25.0, 90.0, -70.0, 50.0, -40.0, 30.0,
        ];
        for (kind, m, pose) in machine_poses([150.0, 0.0, 100.0]) {
            let a = m.displacement(&pose, &le, [10.0, -5.0, 8.0, 3.0, -4.0, 6.0]);
            let b = m.displacement_linear(&pose, &le, [10.0, -5.0, 8.0, 3.0, -4.0, 6.0]);
            for i in 0..3 {
                assert!((a[i] - b[i]).abs() < 0.05, "{kind:?}: {a:?} vs {b:?}");
            }
        }
    }

    /// Reference: zero errors give zero displacement exactly (tolerance 1e-9 µm, rounding).
    #[test]
    fn nominal_machine_reads_zero() {
        for (kind, m, pose) in machine_poses([150.0, 20.0, 100.0]) {
            let d = m.displacement(&pose, &[0.0; N_LOCATION], [0.0; N_SETUP]);
            assert!(d.iter().all(|x| x.abs() < 1e-9), "{kind:?}: {d:?}");
        }
    }
}
