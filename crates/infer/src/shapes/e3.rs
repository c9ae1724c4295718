//! The built-in shape experiment `e3`: one scenario file per object class, sharing the whisker
//! array, the timing and the motion (docs/shapes.md restates it).
//!
//! Five `w30` whiskers (`c1` … `c5`) fan out from points on an arc of radius 5 mm centred 5 mm
//! behind the middle whisker's base, at −30°, −15°, 0°, 15° and 30° from +x, so that each meets
//! a passing object's outline at other angles; the middle one (`c3`) is the seed's whisker at
//! the origin. One, three or five of them are read (`c3`; `c2`–`c4`; all). An object of one of
//! four classes starts with its reference point (centre) at (x, −32 mm), clear of every whisker,
//! and moves along +y at v, past every whisker it reaches; 200 ms at 1 kHz.

/// The array, timing and whisker common to every class (TOML).
macro_rules! e3_common {
    () => {
        r#"duration = 0.2
sample_rate = 1000
dt = 1e-4
segments = 20

[whisker]
preset = "w30"

# A fan of five whiskers 15° apart, bases on an arc of radius 5 mm about (-5 mm, 0).
[[whiskers]]
name = "c1"
position = [-6.698730e-04, -2.500000e-03]
angle = -0.5235987755982988

[[whiskers]]
name = "c2"
position = [-1.703709e-04, -1.294095e-03]
angle = -0.2617993877991494

[[whiskers]]
name = "c3"
position = [0.000000e+00, 0.000000e+00]
angle = 0.0

[[whiskers]]
name = "c4"
position = [-1.703709e-04, 1.294095e-03]
angle = 0.2617993877991494

[[whiskers]]
name = "c5"
position = [-6.698730e-04, 2.500000e-03]
angle = 0.5235987755982988
"#
    };
}

/// The class `box`: a square of side 6–12 mm, turned 0–60° (a quarter turn is a symmetry; the
/// range stops short of it so that every pose is one angle).
pub const BOX: &str = concat!(
    "# e3, class `box`: a square moving along +y past a fan of five w30 whiskers.\n",
    e3_common!(),
    r#"
[[objects]]
shape = "square"
side = 0.009
position = [0.024, -0.032]
angle = 0.5
velocity = [0.0, 0.9]

[unknowns]
"objects.0.position.0" = { range = [0.018, 0.030], name = "x" }
"objects.0.angle" = { range = [0.0, 1.0471975511965976], name = "angle" }
"objects.0.side" = { range = [0.006, 0.012], name = "side" }
"objects.0.velocity.1" = { range = [0.3, 1.5], name = "v" }
"#
);

/// The class `circle`: a peg of radius 3–6 mm (no rotation).
pub const CIRCLE: &str = concat!(
    "# e3, class `circle`: a peg moving along +y past a fan of five w30 whiskers.\n",
    e3_common!(),
    r#"
[[objects]]
shape = "circle"
radius = 0.0045
position = [0.024, -0.032]
velocity = [0.0, 0.9]

[unknowns]
"objects.0.position.0" = { range = [0.018, 0.030], name = "x" }
"objects.0.radius" = { range = [0.003, 0.006], name = "radius" }
"objects.0.velocity.1" = { range = [0.3, 1.5], name = "v" }
"#
);

/// The class `triangle`: an equilateral triangle of side 8–14 mm, turned 0–90° from a vertex
/// pointing along +y (a third of a turn is a symmetry).
pub const TRIANGLE: &str = concat!(
    "# e3, class `triangle`: an equilateral triangle moving along +y past a fan of five w30 whiskers.\n",
    e3_common!(),
    r#"
[[objects]]
shape = "triangle"
side = 0.011
position = [0.024, -0.032]
angle = 0.8
velocity = [0.0, 0.9]

[unknowns]
"objects.0.position.0" = { range = [0.018, 0.030], name = "x" }
"objects.0.angle" = { range = [0.0, 1.5707963267948966], name = "angle" }
"objects.0.side" = { range = [0.008, 0.014], name = "side" }
"objects.0.velocity.1" = { range = [0.3, 1.5], name = "v" }
"#
);

/// The class `wall`: the edge of a plane, a straight plate 40 mm long and 2 mm thick whose
/// near end lies 18–30 mm from the middle whisker's base, turned ±15° (its centre, the
/// reference point, 20 mm beyond its near end).
pub const WALL: &str = concat!(
    "# e3, class `wall`: a 40 mm plate (a plane's edge) moving along +y past a fan of five w30 whiskers.\n",
    e3_common!(),
    r#"
[[objects]]
shape = "box"
width = 0.04
height = 0.002
position = [0.044, -0.032]
angle = 0.0
velocity = [0.0, 0.9]

[unknowns]
"objects.0.position.0" = { range = [0.038, 0.050], name = "x" }
"objects.0.angle" = { range = [-0.2617993877991494, 0.2617993877991494], name = "angle" }
"objects.0.velocity.1" = { range = [0.3, 1.5], name = "v" }
"#
);

/// The classes of `e3`, by name, in the order of its class posteriors.
pub const CLASSES: [(&str, &str); 4] = [
    ("wall", WALL),
    ("box", BOX),
    ("circle", CIRCLE),
    ("triangle", TRIANGLE),
];

/// The active variant `e3-active`: the same fan whisked against a still object. Every whisker's
/// base turns as `−A·cos(2πft)` (A = 0.8 rad, f = 2.5 Hz): at rest retracted by 46° at t = 0, it
/// protracts smoothly to +46° at 200 ms (the half cycle of a slow whisk, peak 12.6 rad/s), and
/// sweeps into an object that lies ahead of the fan's +y side, clear of it at the start.
macro_rules! e3_active_common {
    () => {
        concat!(
            e3_common!(),
            r#"
# Every whisker whisks: -0.8 cos(2 pi 2.5 t) rad about its base, retracted at t = 0.
[base]
kind = "sinusoid"
amplitude = 0.8
frequency = 2.5
phase = -1.5707963267948966
"#
        )
    };
}

/// `e3-active`, class `box`: a still square of side 6–12 mm, turned 0–60°, centred at x 15–25 mm,
/// y 10–16 mm.
pub const ACTIVE_BOX: &str = concat!(
    "# e3-active, class `box`: a fan of five w30 whiskers whisked against a still square.\n",
    e3_active_common!(),
    r#"
[[objects]]
shape = "square"
side = 0.009
position = [0.020, 0.013]
angle = 0.5

[unknowns]
"objects.0.position.0" = { range = [0.015, 0.025], name = "x" }
"objects.0.position.1" = { range = [0.010, 0.016], name = "y" }
"objects.0.angle" = { range = [0.0, 1.0471975511965976], name = "angle" }
"objects.0.side" = { range = [0.006, 0.012], name = "side" }
"#
);

/// `e3-active`, class `circle`: a still peg of radius 3–6 mm, centred as the box.
pub const ACTIVE_CIRCLE: &str = concat!(
    "# e3-active, class `circle`: a fan of five w30 whiskers whisked against a still peg.\n",
    e3_active_common!(),
    r#"
[[objects]]
shape = "circle"
radius = 0.0045
position = [0.020, 0.013]

[unknowns]
"objects.0.position.0" = { range = [0.015, 0.025], name = "x" }
"objects.0.position.1" = { range = [0.010, 0.016], name = "y" }
"objects.0.radius" = { range = [0.003, 0.006], name = "radius" }
"#
);

/// `e3-active`, class `triangle`: a still equilateral triangle of side 8–14 mm, turned 0–90°,
/// centred as the box.
pub const ACTIVE_TRIANGLE: &str = concat!(
    "# e3-active, class `triangle`: a fan of five w30 whiskers whisked against a still triangle.\n",
    e3_active_common!(),
    r#"
[[objects]]
shape = "triangle"
side = 0.011
position = [0.020, 0.013]
angle = 0.8

[unknowns]
"objects.0.position.0" = { range = [0.015, 0.025], name = "x" }
"objects.0.position.1" = { range = [0.010, 0.016], name = "y" }
"objects.0.angle" = { range = [0.0, 1.5707963267948966], name = "angle" }
"objects.0.side" = { range = [0.008, 0.014], name = "side" }
"#
);

/// `e3-active`, class `wall`: a plane ahead of the fan, a still plate 40 mm × 2 mm centred at
/// x = 20 mm and y 12–18 mm, turned ±15°.
pub const ACTIVE_WALL: &str = concat!(
    "# e3-active, class `wall`: a fan of five w30 whiskers whisked against a still plate (a plane).\n",
    e3_active_common!(),
    r#"
[[objects]]
shape = "box"
width = 0.04
height = 0.002
position = [0.020, 0.015]
angle = 0.0

[unknowns]
"objects.0.position.1" = { range = [0.012, 0.018], name = "y" }
"objects.0.angle" = { range = [-0.2617993877991494, 0.2617993877991494], name = "angle" }
"#
);

/// The classes of `e3-active`, in the order of `e3`'s.
pub const ACTIVE_CLASSES: [(&str, &str); 4] = [
    ("wall", ACTIVE_WALL),
    ("box", ACTIVE_BOX),
    ("circle", ACTIVE_CIRCLE),
    ("triangle", ACTIVE_TRIANGLE),
];

/// Whiskers read with 1, 3 and 5 whiskers.
pub const SUBSETS: [&[&str]; 3] = [
    &["c3"],
    &["c2", "c3", "c4"],
    &["c1", "c2", "c3", "c4", "c5"],
];
