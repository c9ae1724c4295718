//! Contact between the whisker and rigid kinematic objects, as constraints.
//!
//! Contacts are found at the step's geometric evaluation point: for every object near the
//! whisker and every segment, the nearest points of the segment's axis and the object; a pair
//! closer than the whisker's radius plus what the relative motion can close in a step is a
//! candidate. Each candidate gets a normal force `λn ≥ 0` (and, with friction, a tangential
//! force `|λt| ≤ μ·λn`) chosen so that, to first order, the whisker's surface ends the step on
//! or outside the object (`gap ≥ 0`, `λn·gap = 0`: Signorini's condition at the end of the
//! step) and, while sticking, its contact point has no tangential velocity relative to the object.
//!
//! The step is linear in these forces at fixed geometry: the articulated-body factorisation of
//! `M + A` from the unconstrained solve is reused to apply `(M + A)⁻¹` to each contact's
//! generalised force, which gives the small Delassus matrix of the contacts; a projected
//! Gauss–Seidel iteration (or, without friction, exact pivoting) solves the resulting
//! complementarity problem. The forces then enter the step by superposition on the unconstrained
//! solve: the joint accelerations gain each force's response, and the base reaction its change of
//! the articulated bias force at the base, so everything downstream includes them without a second
//! articulated solve. No penalty stiffness is involved,
//! so contact keeps the time step of the free whisker.
//!
//! A contact is active when the step would end in penetration without it, and its normal force
//! makes the contact point's normal velocity relative to the object non-negative at the end of
//! the step (a perfectly inelastic contact, as in Moreau's time stepping); friction holds the
//! tangential velocity at zero up to μ·N.
//!
//! A new contact (an object that carried no force in the previous step) is an impulse: its
//! acceleration changes the rates by `h·a` and the angles by `h²/2·a`, and stays out of the
//! method's acceleration history, so an impact that ends with its step is not applied again in
//! the next (which made the whisker rebound and gain energy). A lasting contact's force is
//! integrated like any other force, with the method's own weights (second order, so slowly
//! loaded contacts match statics); when it ends, the step is taken again without that force in
//! the history. What penetration remains (up to `h·v/2` after a fast impact) is removed by moving
//! the angles, not the rates, along the static compliance `K⁻¹Jᵀ`.

pub use super::state::ContactReport;
pub use super::workspace::{Scratch, MAX_CONTACTS};

use super::inputs::Inputs;
use super::integrator::Stepper;
use super::reach;
use super::workspace::{Candidate, Workspace};
use crate::chain::Model;
use crate::error::Result;
use crate::objects::{bounds, closest, Closest};
use crate::planar::{fma, shift_force};

impl Scratch {
    /// Forgets the last solve's contacts (a step without objects).
    pub(crate) fn clear(&mut self) {
        if self.count > 0 {
            self.count = 0;
            self.acc.fill(0.0);
            self.acc_lasting.fill(0.0);
            self.position_fix.fill(0.0);
            self.forced = false;
        }
    }

    /// Bit k set when object k carried contact force in the last solve (objects 0..63).
    pub(crate) fn touching(&self) -> u64 {
        self.cand[..self.count]
            .iter()
            .filter(|c| c.lambda_n > 0.0)
            .fold(0, |m, c| m | (1u64 << c.object.min(63)))
    }

    /// The features of the whisker that carried contact force in the last solve (see
    /// [`feature_bit`]).
    pub(crate) fn held(&self) -> u128 {
        self.cand[..self.count]
            .iter()
            .filter(|c| c.lambda_n > 0.0)
            .fold(0, |m, c| m | feature_bit(c))
    }

    /// The report of the last solve (`None` without objects or contact force).
    pub(crate) fn report(&self, model: &Model, no_objects: bool) -> Option<ContactReport> {
        if no_objects {
            return None;
        }
        let active = || self.cand[..self.count].iter().filter(|c| c.lambda_n > 0.0);
        let count = active().count();
        let c = active().min_by(|a, b| a.s.total_cmp(&b.s))?;
        let _ = model;
        Some(ContactReport {
            point: c.point,
            s: c.s,
            force: [
                c.lambda_n * c.n[0] + c.lambda_t * c.t[0],
                c.lambda_n * c.n[1] + c.lambda_t * c.t[1],
            ],
            normal: c.n,
            normal_force: c.lambda_n,
            tangential_force: c.lambda_t,
            count,
            object: c.object,
        })
    }
}

/// The share of its gap that a held contact ([`Integrator::hold_contacts`](super::Integrator::hold_contacts)), open at the end of
/// the step, may close within the step (its row: `v_end ≥ −HELD_CLOSING · gap / h`).
///
/// Without held contacts, a whisker's tip pressed against a surface that turns away from it (a
/// peg sliding past the tip) lost contact for one step whenever the step's end found it a few
/// micrometres off the surface, sprang back and struck it again in the next: the base forces
/// flickered by several times the sensor noise from one step to the next, and which steps
/// flickered changed with sub-micrometre moves of the object. Holding such a contact at zero
/// closing speed (a share of 0) lets the gap grow until it releases anyway; closing all of it (1)
/// overshoots, and the contact force rings at two steps' period. Half was measured to give a
/// smooth force (docs/contact.md, "Held contacts").
const HELD_CLOSING: f64 = 0.5;

/// A contact candidate's feature of the whisker as a bit: bit 2i for a point within segment i,
/// bit 2i + 1 for its far node, for segments 0..63. A longer chain's further features have no
/// bit, so their contacts are judged afresh every step (none is held).
fn feature_bit(c: &Candidate) -> u128 {
    let bit = 2 * c.seg + usize::from(c.node);
    if bit < 128 {
        1u128 << bit
    } else {
        0
    }
}

/// The step's starting angles, rates and accelerations.
pub(crate) struct StepStart<'a> {
    pub q: &'a [f64],
    pub v: &'a [f64],
    pub a: &'a [f64],
    /// Objects that carried contact force in the previous step (bit k for object k).
    pub touching: u64,
    /// Features of the whisker that carried contact force in the previous step (see
    /// [`feature_bit`]).
    pub held: u128,
    /// How far the base turns between the evaluation point's time and the end of the step, rad.
    pub base_turn: f64,
    /// The base's angular rate at the end of the step, rad/s.
    pub base_rate: f64,
}

/// Generalised force of a unit world force `f` at world point `p` of segment `seg`:
/// joint j ≤ seg gets `(p - p_j) × f`.
fn generalised(ws: &Workspace, seg: usize, p: [f64; 2], f: [f64; 2], out: &mut [f64]) {
    let (moved, still) = out.split_at_mut((seg + 1).min(out.len()));
    for (o, r) in moved.iter_mut().zip(&ws.node) {
        *o = (p[0] - r[0]) * f[1] - (p[1] - r[1]) * f[0];
    }
    still.fill(0.0);
}

/// Response of the joint accelerations to a unit world force `f` at world point `p` of segment
/// `seg`: `x = (M + A)⁻¹ Jᵀ f`, with the articulated-body quantities of the last solve (no
/// velocity terms, no base acceleration). Returns the change of the articulated bias force at the
/// base, which with `x[0]` gives the change of the base reaction (superposition: the articulated
/// solve is linear in the external forces).
fn apply_inverse(
    ws: &Workspace,
    seg: usize,
    p: [f64; 2],
    f: [f64; 2],
    u: &mut [f64],
    x: &mut [f64],
) -> [f64; 3] {
    let n = ws.n;
    let (segs, node) = (&ws.seg[..n], &ws.node[..=n]);
    // Inward pass: the force as a spatial force about its segment's joint, carried to the base.
    u[seg + 1..n].fill(0.0);
    let o = node[seg];
    let mut pa = [-((p[0] - o[0]) * f[1] - (p[1] - o[1]) * f[0]), -f[0], -f[1]];
    for i in (0..=seg).rev() {
        let sg = &segs[i];
        let ui = -pa[0];
        u[i] = ui;
        if i == 0 {
            break;
        }
        let k = ui * sg.inv_d;
        let uv = sg.u_vec;
        let pa_a = [
            fma(uv[0], k, pa[0]),
            fma(uv[1], k, pa[1]),
            fma(uv[2], k, pa[2]),
        ];
        let (pp, pi) = (node[i - 1], node[i]);
        pa = shift_force(pa_a, pp[0] - pi[0], pp[1] - pi[1]);
    }
    // Outward pass.
    let mut acc = [0.0f64; 3];
    for i in 0..n {
        if i > 0 {
            let (p, o) = (node[i - 1], node[i]);
            let (dx, dy) = (o[0] - p[0], o[1] - p[1]);
            acc = [acc[0], fma(-acc[0], dy, acc[1]), fma(acc[0], dx, acc[2])];
        }
        let sg = &segs[i];
        let uv = sg.u_vec;
        let xi = (u[i] - fma(uv[0], acc[0], fma(uv[1], acc[1], uv[2] * acc[2]))) * sg.inv_d;
        acc[0] += xi;
        x[i] = xi;
    }
    pa
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Stage: find contacts at the evaluation point, solve for their forces, and add them to the step
/// (by superposition on the unconstrained solve). `t0` is the time at the start of the step.
/// A contact at the tip whose line of action passes closer than this share of the whisker's
/// length to every joint counts as end-on.
const END_ON_ARM: f64 = 0.02;

/// The normal of a contact at the whisker's tip (`nodes`: the chain's nodes, the tip last):
/// `normal` itself, unless the object meets the tip end-on — the force's line through the tip
/// passes within [`END_ON_ARM`] of the whisker's length of every joint, the object moves
/// (velocity `v_obj`) towards the base along the last segment and reaches the tip within the
/// step (its motion over the step `d_obj` closes the `gap`). No joint can then yield to the
/// force by bending: the chain has no axial compliance, such a contact has no finite force
/// that keeps it, and the step diverges. A slender whisker's tip yields sideways instead, in
/// the direction the object moves across the last segment (or, for a push straight along it,
/// the side the normal leans to), so the object pushes it aside and slips past. A curved
/// whisker pressed end-on keeps its normal: the force has an arm about its base.
fn end_on_normal(
    normal: [f64; 2],
    nodes: &[[f64; 2]],
    v_obj: [f64; 2],
    gap: f64,
    d_obj: [f64; 2],
) -> [f64; 2] {
    let [.., a, tip] = nodes else {
        return normal;
    };
    let (dx, dy) = (tip[0] - a[0], tip[1] - a[1]);
    let len = (dx * dx + dy * dy).sqrt();
    if len <= 0.0 {
        return normal;
    }
    let axis = [dx / len, dy / len];
    let length = len * (nodes.len() - 1) as f64;
    let arm = nodes
        .iter()
        .map(|p| ((p[0] - tip[0]) * normal[1] - (p[1] - tip[1]) * normal[0]).abs())
        .fold(0.0, f64::max);
    let closing = v_obj[0] * axis[0] + v_obj[1] * axis[1] < 0.0;
    let reaches = gap - (normal[0] * d_obj[0] + normal[1] * d_obj[1]) < 0.0;
    if arm >= END_ON_ARM * length || !closing || !reaches {
        return normal;
    }
    let side = [-axis[1], axis[0]];
    let across = v_obj[0] * side[0] + v_obj[1] * side[1];
    let lean = normal[0] * side[0] + normal[1] * side[1];
    let sign = if across != 0.0 {
        across.signum()
    } else if lean != 0.0 {
        lean.signum()
    } else {
        1.0
    };
    [sign * side[0], sign * side[1]]
}

pub(crate) fn solve(
    model: &Model,
    st: &Stepper,
    ws: &mut Workspace,
    inputs: &Inputs,
    start: &StepStart,
    t0: f64,
) -> Result<()> {
    let n = model.n;
    let h = st.dt;
    let (beta, gamma, am) = (st.beta_coef(), st.gamma_coef(), st.alpha_m_coef());
    let t_end = t0 + h;

    // Broad phase: the whisker's bounding box at the evaluation point.
    let wb = reach::whisker_bounds(n, |i| ws.node[i]);
    let rmax = reach::largest_radius(model);

    // Narrow phase: candidates.
    let mut count = 0usize;
    for (k, obj) in inputs.objects.iter().enumerate() {
        // An object out of the whisker's plane at the end of the step cannot hold it.
        if !obj.in_plane(t_end) {
            continue;
        }
        // Features are found with the object where it starts the step, so that a fast object
        // cannot jump past a feature of the whisker (its tip) within one step; its motion over the
        // step enters the end-of-step gap.
        let pose = obj.pose(t0);
        let pose_end = obj.pose(t_end);
        // Reach: how far the object and the whisker can close in a step, plus the radius.
        let wmax = reach::whisker_speed(model, |i| ws.seg[i].vel);
        let reach = reach::reach(rmax, h, pose.velocity, pose.angular_velocity, wmax);
        let ob = bounds(&obj.shape, &pose);
        if reach::beyond(ob, wb, reach) {
            continue;
        }
        let mut prev_tip: Option<[f64; 2]> = None;
        for i in 0..n {
            let (a, b) = (ws.node[i], ws.node[i + 1]);
            // A segment whose bounding box is beyond reach of the object's cannot touch it.
            if a[0].min(b[0]) > ob[2] + reach
                || a[0].max(b[0]) < ob[0] - reach
                || a[1].min(b[1]) > ob[3] + reach
                || a[1].max(b[1]) < ob[1] - reach
            {
                prev_tip = None;
                continue;
            }
            // Candidates: the segment's nearest point, and its far node when that is near too (a
            // segment lying along a face touches it at both ends). A node shared with the previous
            // segment is taken once.
            let near = closest(&obj.shape, &pose, a, b);
            // The far node's distance to the object's bounding box bounds its gap from below.
            let bx = (ob[0] - b[0]).max(b[0] - ob[2]).max(0.0);
            let by = (ob[1] - b[1]).max(b[1] - ob[3]).max(0.0);
            let end = if near.u < 1.0 && bx * bx + by * by <= reach * reach {
                let a2 = [b[0] - 1e-6 * (b[0] - a[0]), b[1] - 1e-6 * (b[1] - a[1])];
                let e = closest(&obj.shape, &pose, a2, b);
                Some(Closest {
                    u: 1.0,
                    on_whisker: b,
                    ..e
                })
            } else {
                None
            };
            let taken = prev_tip;
            prev_tip = None;
            // By reference: an iterator that moves the candidates copies each of them.
            let found = [Some(near), end];
            for c in found.iter().flatten() {
                if c.u <= 0.0 && taken.is_some_and(|p| p == c.on_whisker) {
                    continue;
                }
                let radius = model.radius[i] + c.u * (model.radius[i + 1] - model.radius[i]);
                let gap = c.distance - radius;
                if gap > reach - rmax {
                    continue;
                }
                if c.u >= 1.0 {
                    prev_tip = Some(c.on_whisker);
                }
                // When full, a closer candidate replaces the farthest one.
                let slot = if count < MAX_CONTACTS {
                    count += 1;
                    count - 1
                } else {
                    let (far, far_gap) = ws.contacts.cand[..count]
                        .iter()
                        .enumerate()
                        .map(|(j, c)| (j, c.gap))
                        .fold((0, f64::NEG_INFINITY), |a, b| if b.1 > a.1 { b } else { a });
                    if gap >= far_gap {
                        continue;
                    }
                    far
                };
                // Object motion over the step, at the object's contact point.
                let local = pose.to_local(c.on_object);
                let o_end = pose_end.to_world(local);
                let d_obj = [o_end[0] - c.on_object[0], o_end[1] - c.on_object[1]];
                let v_obj = pose_end.velocity_at(o_end);
                let nrm = if i + 1 == n && c.u >= 1.0 {
                    end_on_normal(c.normal, &ws.node[..=n], v_obj, gap, d_obj)
                } else {
                    c.normal
                };
                let tan = [-nrm[1], nrm[0]];
                ws.contacts.cand[slot] = Candidate {
                    gap,
                    seg: i,
                    point: c.on_whisker,
                    node: c.u >= 1.0,
                    s: (i as f64 + c.u) * model.arc,
                    n: nrm,
                    t: tan,
                    c_n: gap - (nrm[0] * d_obj[0] + nrm[1] * d_obj[1]),
                    c_t: -(tan[0] * v_obj[0] + tan[1] * v_obj[1]),
                    mu: obj.friction,
                    object: k,
                    g_pred: 0.0,
                    active: false,
                    impact: start.touching & (1u64 << k.min(63)) == 0,
                    c_v: -(nrm[0] * v_obj[0] + nrm[1] * v_obj[1]),
                    lambda_n: 0.0,
                    lambda_t: 0.0,
                };
            }
        }
    }
    ws.contacts.count = count;
    // The contact accelerations and the penetration fix start at zero; they are written only
    // where a force or a fix is added, so they need zeroing only after one was.
    if ws.contacts.forced {
        ws.contacts.acc.fill(0.0);
        ws.contacts.acc_lasting.fill(0.0);
        ws.contacts.position_fix.fill(0.0);
        ws.contacts.forced = false;
    }
    if count == 0 {
        return Ok(());
    }

    // End-of-step angles and rates as affine functions of b.
    let cq = h * h * beta / (1.0 - am);
    let cv = h * gamma / (1.0 - am);
    {
        let c = &mut ws.contacts;
        let kq = h * h * (0.5 - beta - beta * am / (1.0 - am));
        let kv = h * (1.0 - gamma - gamma * am / (1.0 - am));
        // Slices of one length, so that the loop indexes without checks.
        let (sq, sv, sa) = (&start.q[..n], &start.v[..n], &start.a[..n]);
        let (q0, v0) = (&mut c.q0[..n], &mut c.v0[..n]);
        for i in 0..n {
            let (q, v, a) = (sq[i], sv[i], sa[i]);
            q0[i] = q + h * v + kq * a;
            v0[i] = v + kv * a;
        }
    }

    // Generalised forces of unit normal/tangential forces, J.
    let mut jac = std::mem::take(&mut ws.contacts.jac);
    let mut resp = std::mem::take(&mut ws.contacts.resp);
    let mut u = std::mem::take(&mut ws.contacts.u);
    for k in 0..count {
        let c = ws.contacts.cand[k];
        generalised(
            ws,
            c.seg,
            c.point,
            c.n,
            &mut jac[2 * k * n..(2 * k + 1) * n],
        );
        let jt = &mut jac[(2 * k + 1) * n..(2 * k + 2) * n];
        // A frictionless candidate's tangential row is never read (its Delassus entries are zero
        // by its friction coefficient, and it takes no tangential force), so it is not written.
        if c.mu > 0.0 {
            generalised(ws, c.seg, c.point, c.t, jt);
        } else if c.mu != 0.0 {
            jt.fill(0.0);
        }
    }

    // Constant terms: the end-of-step gap and slip velocity with the unconstrained b.
    let m = 2 * count;
    let sc = &mut ws.contacts;
    for k in 0..count {
        let (jn, jt) = (
            &jac[2 * k * n..(2 * k + 1) * n],
            &jac[(2 * k + 1) * n..(2 * k + 2) * n],
        );
        // Whisker point displacement from the evaluation point: J (q_end - q_eval). A
        // frictionless candidate's slip velocity is not needed (nor its tangential row written).
        let frictionless = sc.cand[k].mu == 0.0;
        let mut dn = 0.0;
        let mut vt = 0.0;
        let mut vn = 0.0;
        // Slices of one length, so that the loop indexes without checks.
        let (q0, v0, qdd, q) = (&sc.q0[..n], &sc.v0[..n], &ws.qdd[..n], &ws.q[..n]);
        for i in 0..n {
            let q_end = q0[i] + cq * qdd[i];
            let v_end = v0[i] + cv * qdd[i];
            dn += jn[i] * (q_end - q[i]);
            vn += jn[i] * v_end;
            if !frictionless {
                vt += jt[i] * v_end;
            }
        }
        // The base's own rotation: its turn over the rest of the step moves the point, and its
        // rate at the end adds to the point's velocity (the joint angles are relative to it).
        let c = &mut sc.cand[k];
        let o = ws.node[0];
        let arm = [-(c.point[1] - o[1]), c.point[0] - o[0]];
        let along = |d: [f64; 2]| d[0] * arm[0] + d[1] * arm[1];
        let (an, at) = (along(c.n), along(c.t));
        c.c_n += dn + start.base_turn * an;
        if !frictionless {
            c.c_t += vt + start.base_rate * at;
        }
        c.c_v += vn + start.base_rate * an;
        // Active when the step would end in penetration without a contact force; the normal row is
        // then the end-of-step normal velocity (an inelastic contact: v ≥ 0). A held contact (its
        // object and its segment carried force in the previous step) is active too when the step
        // would end with it open but still closing fast enough to penetrate within the next step:
        // its row then lets it close a share of the gap instead of none (see `HELD_CLOSING`).
        let g = c.c_n;
        let held = st.hold_contacts && !c.impact && start.held & feature_bit(c) != 0;
        c.active = g <= 0.0 || (held && g + h * c.c_v < 0.0);
        c.g_pred = g;
        c.c_n = if g > 0.0 {
            c.c_v + HELD_CLOSING * g / h
        } else {
            c.c_v
        };
    }
    // Only active candidates take force: their responses (M + A)⁻¹ Jᵀ, and the Delassus columns
    // they own. Rows stay complete, for the gaps that post-stabilisation checks.
    let mut act = [0usize; MAX_CONTACTS];
    let mut na = 0;
    for k in 0..count {
        if sc.cand[k].active {
            act[na] = k;
            na += 1;
        }
    }
    let act = &act[..na];
    if na == 0 {
        // No candidate takes force: every force stays zero, no gap is left negative (an inactive
        // candidate's predicted gap is positive), and the step is the unconstrained one. The
        // superposition below would add zeros to the base reaction and the first joint's
        // acceleration (which turns a negative zero there into a positive one); so does this.
        ws.contacts.jac = jac;
        ws.contacts.resp = resp;
        ws.contacts.u = u;
        for p in ws.pa0.iter_mut() {
            *p += 0.0;
        }
        ws.seg[0].acc[0] += 0.0;
        return Ok(());
    }
    // The changes of the base's bias force, per row; only the rows of active candidates are
    // written and read (no other row takes force).
    let mut base_resp = std::mem::take(&mut ws.contacts.base_resp);
    for &k in act {
        let mu = ws.contacts.cand[k].mu;
        let rows: &[usize] = if mu > 0.0 {
            &[2 * k, 2 * k + 1]
        } else {
            &[2 * k]
        };
        let c = ws.contacts.cand[k];
        for &r in rows {
            let dir = if r % 2 == 0 { c.n } else { c.t };
            base_resp[r] = apply_inverse(
                ws,
                c.seg,
                c.point,
                dir,
                &mut u,
                &mut resp[r * n..(r + 1) * n],
            );
        }
        if mu == 0.0 {
            resp[(2 * k + 1) * n..(2 * k + 2) * n].fill(0.0);
        }
    }
    let sc = &mut ws.contacts;
    // Delassus matrix: every row is a velocity at the end of the step. An impact's force changes
    // the rates by h times its acceleration; a lasting contact's force is integrated like any
    // other force (by the method's own weights).
    // Tangential rows and columns of frictionless candidates are zero (their J rows are).
    for r in 0..m {
        let row_zero = r % 2 == 1 && sc.cand[r / 2].mu == 0.0;
        for &k in act {
            let scale = if sc.cand[k].impact { h } else { cv };
            for col in [2 * k, 2 * k + 1] {
                sc.w[r * m + col] = if row_zero || (col % 2 == 1 && sc.cand[k].mu == 0.0) {
                    0.0
                } else {
                    scale * dot(&jac[r * n..(r + 1) * n], &resp[col * n..(col + 1) * n])
                };
            }
        }
    }

    // Frictionless contacts: the complementarity problem solved exactly by pivoting on the active
    // set; with friction (or if pivoting fails), projected Gauss–Seidel over the active candidates.
    let frictionless = act.iter().all(|&k| sc.cand[k].mu == 0.0);
    let pivoted = frictionless && pivot_normal(sc, act, m);
    let sweeps = if pivoted { 0 } else { 2000 };
    for _ in 0..sweeps {
        let mut change = 0.0f64;
        for &k in act {
            let (rn, rt) = (2 * k, 2 * k + 1);
            // Normal: gap at the end of the step >= 0, force >= 0.
            let mut g = sc.cand[k].c_n;
            for &j in act {
                g += sc.w[rn * m + 2 * j] * sc.cand[j].lambda_n
                    + sc.w[rn * m + 2 * j + 1] * sc.cand[j].lambda_t;
            }
            let old = sc.cand[k].lambda_n;
            let diag = sc.w[rn * m + rn];
            // Points the whisker cannot move (the clamped base) take none.
            let new = if diag > 0.0 {
                (old - g / diag).max(0.0)
            } else {
                0.0
            };
            sc.cand[k].lambda_n = new;
            change = change.max((new - old).abs());
            // Tangential: no slip while |λt| < μ λn.
            if sc.cand[k].mu > 0.0 && sc.w[rt * m + rt] > 0.0 {
                let mut s = sc.cand[k].c_t;
                for &j in act {
                    s += sc.w[rt * m + 2 * j] * sc.cand[j].lambda_n
                        + sc.w[rt * m + 2 * j + 1] * sc.cand[j].lambda_t;
                }
                let bound = sc.cand[k].mu * sc.cand[k].lambda_n;
                let old = sc.cand[k].lambda_t;
                let new = (old - s / sc.w[rt * m + rt]).clamp(-bound, bound);
                sc.cand[k].lambda_t = new;
                change = change.max((new - old).abs());
            } else {
                sc.cand[k].lambda_t = 0.0;
            }
        }
        let scale = act
            .iter()
            .fold(1e-30f64, |a, &k| a.max(sc.cand[k].lambda_n));
        if change <= 1e-12 * scale {
            break;
        }
    }
    ws.contacts.jac = jac;
    ws.contacts.resp = resp;
    ws.contacts.u = u;

    // The contact forces' accelerations, split into impacts and lasting contacts (they are
    // integrated differently).
    for k in 0..count {
        let c = ws.contacts.cand[k];
        for (r, lambda) in [(2 * k, c.lambda_n), (2 * k + 1, c.lambda_t)] {
            if lambda != 0.0 {
                let sc = &mut ws.contacts;
                sc.forced = true;
                let acc = if c.impact {
                    &mut sc.acc
                } else {
                    &mut sc.acc_lasting
                };
                for (a, x) in acc.iter_mut().zip(&sc.resp[r * n..(r + 1) * n]) {
                    *a += lambda * x;
                }
            }
        }
    }
    // Post-stabilisation: the impulses stop the contact points (h²/2 on the angles), which can
    // leave up to h·v/2 of penetration after a fast impact. Move the angles (not the rates) just
    // enough to close it, along the whisker's static compliance K⁻¹Jᵀ: the shape a quasi-static
    // contact force would give, so a slowly loaded contact stays consistent with statics.
    post_stabilise(
        &mut ws.contacts,
        &model.stiffness,
        count,
        n,
        [0.5 * h, cq / cv],
    );
    // The step with the contact forces applied, by superposition on the solve without them: the
    // joint accelerations gain the forces' responses, and the base reaction their bias forces at
    // the base and the first joint's acceleration.
    let mut dpa = [0.0f64; 3];
    let mut dx0 = 0.0;
    for k in 0..count {
        let c = ws.contacts.cand[k];
        for (r, lambda) in [(2 * k, c.lambda_n), (2 * k + 1, c.lambda_t)] {
            if lambda != 0.0 {
                let x = &ws.contacts.resp[r * n..(r + 1) * n];
                for (q, xi) in ws.qdd[..n].iter_mut().zip(x) {
                    *q += lambda * xi;
                }
                dx0 += lambda * x[0];
                for (d, b) in dpa.iter_mut().zip(base_resp[r]) {
                    *d += lambda * b;
                }
            }
        }
    }
    for (p, d) in ws.pa0.iter_mut().zip(dpa) {
        *p += d;
    }
    ws.seg[0].acc[0] += dx0;
    ws.contacts.base_resp = base_resp;
    Ok(())
}

/// Solves the frictionless complementarity problem `g = c + W λ ≥ 0, λ ≥ 0, gᵀλ = 0` on the
/// normal rows of the active candidates `act` by principal pivoting on the set of contacts that
/// carry force: solve for that set with the others free, drop the most negative force or add the
/// most penetrating free contact, repeat. Exact for the few contacts a whisker has at once; returns
/// false (leaving λ = 0) if it does not settle within its pivot budget or meets a singular set.
fn pivot_normal(sc: &mut Scratch, act: &[usize], m: usize) -> bool {
    match *act {
        [k] => pivot_one(sc, k, m),
        _ => pivot_many(sc, act, m),
    }
}

/// [`pivot_normal`] for a single active candidate `k`, to the same bits as [`pivot_many`]: the
/// same steps with the one-by-one matrix `W_kk` and the scalars in place of the arrays.
fn pivot_one(sc: &mut Scratch, k: usize, m: usize) -> bool {
    let w = sc.w[2 * k * m + 2 * k];
    let c = sc.cand[k].c_n;
    let tol = 1e-12 * 1e-300f64.max(c.abs());
    let mut set = c < 0.0;
    for _ in 0..4 * MAX_CONTACTS {
        let mut lambda = 0.0;
        if set {
            // The elimination of `[w | −c]`: singular when its pivot is zero against its scale.
            let scale = f64::MIN_POSITIVE.max(w.abs());
            let p = w.abs();
            if p.is_nan() || p <= 1e-12 * scale {
                return false;
            }
            lambda = -c / w;
            // The contact pulling: dropped.
            if lambda < 0.0 {
                set = false;
                continue;
            }
        } else {
            // The free contact penetrating: added.
            let gap = c + std::iter::once(w * lambda).sum::<f64>();
            if gap < -tol {
                set = true;
                continue;
            }
        }
        let cand = &mut sc.cand[k];
        cand.lambda_n = lambda.max(0.0);
        cand.lambda_t = 0.0;
        return true;
    }
    false
}

/// [`pivot_normal`] for any number of active candidates.
#[allow(clippy::needless_range_loop)]
fn pivot_many(sc: &mut Scratch, act: &[usize], m: usize) -> bool {
    let na = act.len();
    let wn = |sc: &Scratch, a: usize, b: usize| sc.w[2 * act[a] * m + 2 * act[b]];
    let tol = 1e-12
        * act
            .iter()
            .fold(1e-300f64, |a, &k| a.max(sc.cand[k].c_n.abs()));
    let mut set = [false; MAX_CONTACTS];
    let mut lambda = [0.0f64; MAX_CONTACTS];
    // Start from every contact that closes without force of the others.
    for a in 0..na {
        set[a] = sc.cand[act[a]].c_n < 0.0;
    }
    for _ in 0..4 * MAX_CONTACTS {
        // Dense solve of W_SS λ_S = −c_S (Gaussian elimination, partial pivoting).
        let mut map = [0usize; MAX_CONTACTS];
        let mut ns = 0;
        for a in 0..na {
            if set[a] {
                map[ns] = a;
                ns += 1;
            }
        }
        // Rows of the augmented matrix [W_SS | −c_S], stride MAX_CONTACTS + 1.
        const S: usize = MAX_CONTACTS + 1;
        let mut mat = std::mem::take(&mut sc.dense);
        for i in 0..ns {
            for j in 0..ns {
                mat[i * S + j] = wn(sc, map[i], map[j]);
            }
            mat[i * S + ns] = -sc.cand[act[map[i]]].c_n;
        }
        let scale = (0..ns).fold(f64::MIN_POSITIVE, |a, i| a.max(mat[i * S + i].abs()));
        let mut singular = false;
        for col in 0..ns {
            let piv = (col..ns)
                .max_by(|&a, &b| mat[a * S + col].abs().total_cmp(&mat[b * S + col].abs()))
                .unwrap_or(col);
            let p = mat[piv * S + col].abs();
            if p.is_nan() || p <= 1e-12 * scale {
                singular = true;
                break;
            }
            if piv != col {
                for c in col..=ns {
                    mat.swap(col * S + c, piv * S + c);
                }
            }
            for r in col + 1..ns {
                let f = mat[r * S + col] / mat[col * S + col];
                for c in col..=ns {
                    mat[r * S + c] -= f * mat[col * S + c];
                }
            }
        }
        if !singular {
            lambda[..na].fill(0.0);
            for i in (0..ns).rev() {
                let mut x = mat[i * S + ns];
                for j in i + 1..ns {
                    x -= mat[i * S + j] * lambda[map[j]];
                }
                lambda[map[i]] = x / mat[i * S + i];
            }
        }
        sc.dense = mat;
        if singular {
            return false;
        }
        // A contact in the set pulling: drop the most negative.
        let worst = (0..na)
            .filter(|&a| set[a])
            .min_by(|&a, &b| lambda[a].total_cmp(&lambda[b]));
        if let Some(a) = worst.filter(|&a| lambda[a] < 0.0) {
            set[a] = false;
            continue;
        }
        // A free contact penetrating: add the deepest.
        let gap =
            |a: usize| sc.cand[act[a]].c_n + (0..na).map(|b| wn(sc, a, b) * lambda[b]).sum::<f64>();
        let deepest = (0..na)
            .filter(|&a| !set[a])
            .map(|a| (a, gap(a)))
            .min_by(|x, y| x.1.total_cmp(&y.1));
        match deepest {
            Some((a, g)) if g < -tol => set[a] = true,
            _ => {
                for a in 0..na {
                    let c = &mut sc.cand[act[a]];
                    c.lambda_n = lambda[a].max(0.0);
                    c.lambda_t = 0.0;
                }
                return true;
            }
        }
    }
    false
}

/// Moves the end-of-step angles along the static compliance `K⁻¹Jᵀ` just enough to close any gap
/// the contact impulses left negative (see [`solve`]).
#[allow(clippy::needless_range_loop)]
fn post_stabilise(
    sc: &mut Scratch,
    stiffness: &[f64],
    count: usize,
    n: usize,
    to_position: [f64; 2],
) {
    let m = 2 * count;

    let k_inv = |i: usize| 1.0 / stiffness[i];
    // End-of-step gaps after the impulses.
    let mut gap = [0.0f64; MAX_CONTACTS];
    for (k, g) in gap.iter_mut().enumerate().take(count) {
        let rn = 2 * k;
        *g = sc.cand[k].g_pred;
        for (j, cj) in sc.cand[..count].iter().enumerate() {
            // Columns without force are not filled in.
            if cj.lambda_n == 0.0 && cj.lambda_t == 0.0 {
                continue;
            }
            // From a column's rate change to its position change: h/2 (impact), β·h/γ (lasting).
            let f = if cj.impact {
                to_position[0]
            } else {
                to_position[1]
            };
            *g += f * (sc.w[rn * m + 2 * j] * cj.lambda_n + sc.w[rn * m + 2 * j + 1] * cj.lambda_t);
        }
    }
    if gap[..count].iter().any(|g| *g < 0.0) {
        // Static compliance matrix of the contacts' normal directions, J K⁻¹ Jᵀ.
        let mut stat = std::mem::take(&mut sc.stat);
        const S: usize = MAX_CONTACTS;
        for k in 0..count {
            for j in 0..=k {
                let (a, b) = (
                    &sc.jac[2 * k * n..(2 * k + 1) * n],
                    &sc.jac[2 * j * n..(2 * j + 1) * n],
                );
                let v: f64 = (0..n).map(|i| a[i] * b[i] * k_inv(i)).sum();
                stat[k * S + j] = v;
                stat[j * S + k] = v;
            }
        }
        // Smallest non-negative multipliers that close every gap (projected Gauss–Seidel).
        let mut mu = [0.0f64; MAX_CONTACTS];
        for _ in 0..2000 {
            let mut change = 0.0f64;
            for k in 0..count {
                let g = gap[k] + (0..count).map(|j| stat[k * S + j] * mu[j]).sum::<f64>();
                let diag = stat[k * S + k];
                if diag > 0.0 {
                    let new = (mu[k] - g / diag).max(0.0);
                    change = change.max((new - mu[k]).abs() * diag);
                    mu[k] = new;
                }
            }
            if change < 1e-13 {
                break;
            }
        }
        sc.stat = stat;
        for (k, &muk) in mu.iter().enumerate().take(count) {
            if muk > 0.0 {
                sc.forced = true;
                for (i, f) in sc.position_fix.iter_mut().enumerate() {
                    *f += muk * sc.jac[2 * k * n + i] * k_inv(i);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A value for the one-contact problem: mostly ordinary numbers of either sign, sometimes
    /// zeros, tiny, huge or non-finite ones.
    fn value(rng: &mut crate::rng::Rng) -> f64 {
        let special = [
            0.0,
            -0.0,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
            1e-310,
            1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        if rng.uniform() < 0.1 {
            special[(rng.uniform() * special.len() as f64) as usize]
        } else {
            (2.0 * rng.uniform() - 1.0) * 10f64.powf(12.0 * rng.uniform() - 6.0)
        }
    }

    #[test]
    fn one_contact_pivots_to_the_bits_of_the_general_pivot() {
        let mut rng = crate::rng::Rng::stream(7, 0);
        for _ in 0..100_000 {
            let count = 1 + (rng.uniform() * 4.0) as usize;
            let k = (rng.uniform() * count as f64) as usize;
            let m = 2 * count;
            let mut sc = Scratch::new(5);
            sc.count = count;
            sc.w[2 * k * m + 2 * k] = value(&mut rng);
            sc.cand[k].c_n = value(&mut rng);
            // Forces left from elsewhere, which a settled pivot replaces.
            sc.cand[k].lambda_n = value(&mut rng);
            sc.cand[k].lambda_t = value(&mut rng);
            let mut general = sc.clone();
            let (one, many) = (pivot_one(&mut sc, k, m), pivot_many(&mut general, &[k], m));
            let bits = |s: &Scratch| (s.cand[k].lambda_n.to_bits(), s.cand[k].lambda_t.to_bits());
            assert_eq!(one, many);
            assert_eq!(bits(&sc), bits(&general));
        }
    }
}
