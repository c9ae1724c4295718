//! A class's objects at any pose, set field by field: building a particle's objects through the
//! scenario file (a few hundred microseconds) would cost more than stepping it.

use crate::error::{Error, Result};
use crate::family::Family;
use vibrissa_core::objects::{Motion, Object, Shape};

/// The field of an object that one unknown sets.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Field {
    Position(usize),
    Angle,
    Velocity(usize),
    Radius,
    Side,
    Width,
    Height,
}

/// The objects of a class's scenario at any value of its unknowns.
#[derive(Debug, Clone)]
pub(super) struct PoseObjects {
    /// The scene's objects at `p0`.
    base: Vec<Object>,
    /// The unknowns' values `base` was made at.
    p0: Vec<f64>,
    /// Per unknown, the object and the field it sets.
    fields: Vec<(usize, Field)>,
}

/// Fields an unknown may set, as its key names them after `objects.<k>.`.
const FIELDS: [&str; 9] = [
    "position.0",
    "position.1",
    "angle",
    "velocity.0",
    "velocity.1",
    "radius",
    "side",
    "width",
    "height",
];

impl PoseObjects {
    /// The objects of `family` (its unknowns all keys of an object's pose, size or velocity), or
    /// an error naming the first key that is not, checked against the scenario file's own objects
    /// at a few draws of the unknowns.
    pub(super) fn new(family: &Family, method: &str) -> Result<PoseObjects> {
        let refuse = |detail: String| Error::Fit {
            method: method.into(),
            detail: format!("{}: {detail}", family.name()),
        };
        let p0: Vec<f64> = family
            .ranges()
            .iter()
            .map(|[lo, hi]| 0.5 * (lo + hi))
            .collect();
        let base = family.scenario(&p0)?.objects;
        let mut fields = Vec::new();
        for key in family.keys() {
            let parsed = key.strip_prefix("objects.").and_then(|rest| {
                let (k, field) = rest.split_once('.')?;
                let k: usize = k.parse().ok()?;
                let field = match field {
                    "position.0" => Field::Position(0),
                    "position.1" => Field::Position(1),
                    "angle" => Field::Angle,
                    "velocity.0" => Field::Velocity(0),
                    "velocity.1" => Field::Velocity(1),
                    "radius" => Field::Radius,
                    "side" => Field::Side,
                    "width" => Field::Width,
                    "height" => Field::Height,
                    _ => return None,
                };
                (k < base.len()).then_some((k, field))
            });
            let Some(f) = parsed else {
                return Err(refuse(format!(
                    "the unknown `{key}` is not one a particle can carry (objects.<k>. followed by \
                     one of {})",
                    FIELDS.join(", ")
                )));
            };
            fields.push(f);
        }
        let pose = PoseObjects { base, p0, fields };
        for p in family.random_params(3, 0x706f_7365) {
            let want = family.scenario(&p)?.objects;
            let got = pose.objects(&p);
            if !got.iter().zip(&want).all(|(a, b)| close(a, b)) {
                return Err(refuse(format!(
                    "setting its unknowns field by field does not give the scenario's objects at \
                     {} (a key that moves more than its own field?)",
                    family.describe(&p)
                )));
            }
        }
        Ok(pose)
    }

    /// The scene's objects at `p` (one value per unknown).
    pub(super) fn objects(&self, p: &[f64]) -> Vec<Object> {
        let mut out = self.base.clone();
        for (i, &(k, field)) in self.fields.iter().enumerate() {
            let o = &mut out[k];
            let x = p[i];
            match field {
                Field::Position(j) => o.position[j] = x,
                Field::Angle => o.angle = x,
                Field::Velocity(j) => {
                    if let Motion::Constant { velocity, .. } = &mut o.motion {
                        velocity[j] = x;
                    }
                }
                Field::Radius => {
                    if let Shape::Circle { radius } = &mut o.shape {
                        *radius = x;
                    }
                }
                Field::Width => {
                    if let Shape::Box { width, .. } = &mut o.shape {
                        *width = x;
                    }
                }
                Field::Height => {
                    if let Shape::Box { height, .. } = &mut o.shape {
                        *height = x;
                    }
                }
                // A square's side is both its extents; a polygon's scales its outline.
                Field::Side => match &mut o.shape {
                    Shape::Box { width, height } => {
                        *width = x;
                        *height = x;
                    }
                    Shape::Polygon { vertices } => {
                        let scale = x / self.p0[i];
                        for v in vertices.iter_mut() {
                            *v = [v[0] * scale, v[1] * scale];
                        }
                    }
                    Shape::Circle { radius } => *radius = 0.5 * x,
                    Shape::Wall => {}
                },
            }
        }
        out
    }
}

/// Whether two objects agree to rounding in every number.
fn close(a: &Object, b: &Object) -> bool {
    let near = |x: f64, y: f64| (x - y).abs() <= 1e-9 * (1.0 + x.abs().max(y.abs()));
    let motion = match (&a.motion, &b.motion) {
        (
            Motion::Constant {
                velocity: va,
                angular_velocity: wa,
            },
            Motion::Constant {
                velocity: vb,
                angular_velocity: wb,
            },
        ) => near(va[0], vb[0]) && near(va[1], vb[1]) && near(*wa, *wb),
        (x, y) => x == y,
    };
    let shape = match (&a.shape, &b.shape) {
        (
            Shape::Box {
                width: wa,
                height: ha,
            },
            Shape::Box {
                width: wb,
                height: hb,
            },
        ) => near(*wa, *wb) && near(*ha, *hb),
        (Shape::Circle { radius: ra }, Shape::Circle { radius: rb }) => near(*ra, *rb),
        (Shape::Polygon { vertices: va }, Shape::Polygon { vertices: vb }) => {
            va.len() == vb.len()
                && va
                    .iter()
                    .zip(vb)
                    .all(|(p, q)| near(p[0], q[0]) && near(p[1], q[1]))
        }
        (x, y) => x == y,
    };
    motion
        && shape
        && near(a.position[0], b.position[0])
        && near(a.position[1], b.position[1])
        && near(a.angle, b.angle)
        && a.friction == b.friction
        && a.vertical == b.vertical
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::ShapeFamily;

    #[test]
    fn every_class_of_e3_is_set_field_by_field_as_its_file_sets_it() {
        let family = ShapeFamily::builtin("e3").unwrap().unwrap();
        for class in family.classes() {
            let pose = PoseObjects::new(&class.family, "shape-pf").unwrap();
            for p in class.family.random_params(5, 9) {
                let want = class.family.scenario(&p).unwrap().objects;
                assert!(close(&pose.objects(&p)[0], &want[0]), "{}", class.name);
            }
        }
    }

    #[test]
    fn a_key_that_is_not_a_pose_is_refused_by_name() {
        let family = crate::family::Family::open_str(
            &format!(
                "{}\n[unknowns]\n\"whisker.youngs_modulus\" = {{ range = [2e9, 4e9], name = \"E\" }}\n",
                crate::shapes::e3::CIRCLE.split("[unknowns]").next().unwrap()
            ),
            "test",
            &[],
        )
        .unwrap();
        let e = PoseObjects::new(&family, "shape-pf")
            .unwrap_err()
            .to_string();
        assert!(e.contains("whisker.youngs_modulus"), "{e}");
    }
}
