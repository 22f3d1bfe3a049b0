//! Scenes compiled into the binary, so defaults need no files.

/// Names of the built-in scenes; the first is the default.
pub const BUILTIN_NAMES: [&str; 13] = [
    "organ",
    "patch",
    "cantilever",
    "cornea",
    "stretch",
    "patch_cut",
    "keratotomy",
    "cube_tear",
    "cube_shear",
    "gallbladder_fat",
    "liver_cut",
    "bar",
    "large_cut",
];

/// The TOML text of a built-in scene.
pub fn builtin(name: &str) -> Option<&'static str> {
    Some(match name {
        "organ" => ORGAN,
        "patch" => PATCH,
        "cantilever" => CANTILEVER,
        "cornea" => CORNEA,
        "stretch" => STRETCH,
        "patch_cut" => PATCH_CUT,
        "keratotomy" => KERATOTOMY,
        "cube_tear" => CUBE_TEAR,
        "cube_shear" => CUBE_SHEAR,
        "gallbladder_fat" => GALLBLADDER_FAT,
        "liver_cut" => LIVER_CUT,
        "bar" => BAR,
        "large_cut" => LARGE_CUT,
        _ => return None,
    })
}

const ORGAN: &str = r#"# The default scene: palpation of a liver-lobe-like organ.
[scene]
name = "organ"
description = "Palpation of a 16 x 10 x 5 cm organ-like lobe held along its posterior edge; 1.2 N pressed on its upper surface (the load level of seed 001, section 6.2)."

[[organs]]
name = "lobe"
density = 1060.0                     # kg/m3, soft tissue

[organs.mesh]
builtin = "lobe"
semi_axes = [0.08, 0.05, 0.025]      # m
bend = 0.6
divisions = [16, 10, 6]

[[organs.materials]]
region = "all"
model = "linear"
young = 160e3                        # Pa, liver (seed 001)
poisson = 0.45

[organs.fixed]                       # posterior edge, attached to the body wall
half_space = { point = [0.0, -0.04, 0.0], normal = [0.0, -1.0, 0.0] }

[organs.accessible]                  # the upper (anterior) surface
half_space = { point = [0.0, 0.0, 0.005], normal = [0.0, 0.0, 1.0] }

[[organs.loads]]
kind = "point"
at = [0.0, 0.0, 0.04]                # nearest node: the top of the lobe
force = [0.0, 0.0, -1.2]             # N

[[tools]]
kind = "probe"
name = "probe"
radius = 0.004                       # m

[effects]
deformation = "linear"

[fidelity]
locking = "bbar"
"#;

/// The patch model of seed 000 §3.5.1 (organ, mesh, material, supports, load), shared by the
/// `patch` and `patch_cut` scenes.
macro_rules! patch_organ {
    () => {
        r#"[[organs]]
name = "patch"
density = 1.0

[organs.mesh]
builtin = "block"
origin = [0.0, 0.0, 0.0]
size = [5.0, 1.0, 5.0]               # x wide, y deep, z up
divisions = [5, 1, 5]
cell = "hex8"

[[organs.materials]]
model = "linear"
young = 5.0
poisson = 0.3

[organs.fixed]                       # the fully fixed bottom corner
sphere = { center = [0.0, 0.0, 0.0], radius = 0.01 }

[organs.accessible]
half_space = { point = [0.0, 0.0, 5.0], normal = [0.0, 0.0, 1.0] }

[[organs.loads]]                     # base nodes slide on the horizontal plane
kind = "displacement"
name = "base"
region = { box = { min = [0.0, 0.0, 0.0], max = [5.0, 1.0, 0.0] } }
z = 0.0

[[organs.loads]]                     # stops the remaining rotation about the vertical axis
kind = "displacement"
name = "anchor"
region = { sphere = { center = [5.0, 0.0, 0.0], radius = 0.01 } }
y = 0.0

[[organs.loads]]
kind = "point"
at = [5.0, 0.0, 5.0]
force = [0.0, 0.0, -1.0]             # N

"#
    };
}

const PATCH: &str = concat!(
    r#"# Seed 000, section 3.5.1: the patch model (without its cut).
[scene]
name = "patch"
description = "A vertical 5 x 5 grid of unit hexahedra (one cell deep), E = 5 Pa, nu = 0.3; one base corner fully fixed, the other base nodes sliding on the horizontal plane, 1 N down on an upper corner node."

"#,
    patch_organ!(),
    r#"[[tools]]                            # `vademecum run` palpates the top
kind = "probe"
name = "probe"
radius = 0.05

[fidelity]
locking = "none"
"#
);

const LARGE_CUT: &str = r#"# Two effects on one organ: a flap of soft tissue that deforms largely (St Venant-Kirchhoff, its
# own ANM-POD lattice) cut by the scalpel down the middle of its top half, and pressed beside the
# cut by a probe. The cut's force is scaled by the lattice's stiffening of the uncut organ
# (docs/large_deformation.md, "Cutting an organ that deforms largely"); against Newton on the
# organ cut by split nodes in engine/tests/it/large_cut.rs. `vademecum run --builtin large_cut`.
[scene]
name = "large_cut"
description = "A 2 x 1 x 1 m flap (8 x 4 x 4 hexahedra, E = 1 kPa, nu = 0.3, deformation large) clamped at its base, cut by the scalpel down the plane x = 1 through its top half while it deforms largely, and pressed beside the cut by a probe: cutting and large deformations on one organ."

[[organs]]
name = "flap"
density = 1.0
deformation = "large"

[organs.mesh]
builtin = "block"
origin = [0.0, 0.0, 0.0]
size = [2.0, 1.0, 1.0]               # x long, y deep, z up (m)
divisions = [8, 4, 4]
cell = "hex8"

[[organs.materials]]
model = "linear"                     # its E and nu; large deformations take St Venant-Kirchhoff with them
young = 1000.0                       # Pa
poisson = 0.3

[organs.fixed]                       # the base is clamped
half_space = { point = [0.0, 0.0, 0.01], normal = [0.0, 0.0, -1.0] }

[organs.accessible]                  # tools touch the top
half_space = { point = [0.0, 0.0, 0.99], normal = [0.0, 0.0, 1.0] }

[[organs.loads]]                     # the flap's free top corner pulled sideways: opens the cut
kind = "point"
at = [2.0, 0.5, 1.0]
force = [0.5, 0.0, 0.0]              # N

[[organs.cuts]]                      # the blade goes down x = 1 (a plane of cell faces) to half height
blade = [[[1.0, -0.1, 1.1], [1.0, 1.1, 1.1]], [[1.0, -0.1, 0.5], [1.0, 1.1, 0.5]]]

[[tools]]                            # the right hand
kind = "scalpel"
name = "scalpel"
blade_length = 1.2                   # m
cut_force = 1.0                      # N

[[tools]]                            # the left hand
kind = "probe"
name = "probe"
radius = 0.05                        # m
max_force = 60.0                     # N

[effects]
cutting = true

[fidelity]
locking = "none"                     # the standard hexahedron

[fidelity.xfem]
front = "shared"                     # the cut ends where the blade stopped

[fidelity.large]
positions = 4
load_steps = 4
max_force = 40.0                     # N
"#;

const BAR: &str = r#"# A bar clamped at one end, its free end's upper corner loaded: cut through, its end comes loose.
[scene]
name = "bar"
description = "A 4 x 1 x 1 bar of 4 unit hexahedra (E = 100 Pa, nu = 0.3) clamped at x = 0, 1 N down on the upper corner of its free end: the smallest organ a cut can free a piece of (the reduced cutting model's hard case)."

[[organs]]
name = "bar"
density = 1.0

[organs.mesh]
builtin = "block"
size = [4.0, 1.0, 1.0]
divisions = [4, 1, 1]
cell = "hex8"

[[organs.materials]]
model = "linear"
young = 100.0
poisson = 0.3

[organs.fixed]
box = { min = [0.0, 0.0, 0.0], max = [0.0, 1.0, 1.0] }

[organs.accessible]
half_space = { point = [0.0, 0.0, 1.0], normal = [0.0, 0.0, 1.0] }

[[organs.loads]]
kind = "point"
at = [4.0, 0.0, 1.0]
force = [0.0, 0.0, -1.0]

[[tools]]                            # `vademecum run` palpates the top
kind = "probe"
name = "probe"
radius = 0.05
"#;

const CANTILEVER: &str = r#"# A cantilever ten times longer than high under a tip load (compare with beam theory).
[scene]
name = "cantilever"
description = "1 m x 0.1 m x 0.1 m beam clamped at x = 0, 1 N down spread over the tip face."

[[organs]]
name = "beam"
density = 1000.0

[organs.mesh]
builtin = "block"
size = [1.0, 0.1, 0.1]
divisions = [40, 4, 4]
cell = "hex8"

[[organs.materials]]
model = "linear"
young = 1e6
poisson = 0.3

[organs.fixed]
box = { min = [0.0, 0.0, 0.0], max = [0.0, 0.1, 0.1] }

[organs.accessible]
half_space = { point = [0.0, 0.0, 0.1], normal = [0.0, 0.0, 1.0] }

[[organs.loads]]
kind = "force"
region = { box = { min = [1.0, 0.0, 0.0], max = [1.0, 0.1, 0.1] } }
force = [0.0, 0.0, -1.0]

[[tools]]                            # `vademecum run` palpates the top
kind = "probe"
name = "probe"
radius = 0.02

[fidelity]
locking = "none"
"#;

/// The cornea dome of seeds 000 §3.5.2 and 001 §6.1 (mesh, supports, the anterior surface
/// accessible) with the material model `$model`, shared by `cornea` and `keratotomy`.
macro_rules! cornea_organ {
    ($model:literal) => {
        concat!(
            r#"[[organs]]
name = "cornea"
density = 1076.0                     # kg/m3

[organs.mesh]
builtin = "dome"
curvature_radius = 7.8e-3            # m
base_radius = 5.75e-3
thickness = 0.55e-3
divisions = [24, 24, 3]

[[organs.materials]]
model = ""#,
            $model,
            r#""
young = 2e6                          # Pa
poisson = 0.48

[organs.fixed]                       # the base ring (limbus)
half_space = { point = [0.0, 0.0, 0.05e-3], normal = [0.0, 0.0, -1.0] }

[organs.accessible]                  # the anterior surface (a group of the built-in dome)
group = "anterior"

"#
        )
    };
}

const CORNEA: &str = concat!(
    r#"# Seed 001, section 6.1: pinching a cornea-like dome (large deformations).
[scene]
name = "cornea"
description = "A cornea-like spherical cap (radius of curvature 7.8 mm, 11.5 mm across, 0.55 mm thick; 24 x 24 x 3 hexahedra), St Venant-Kirchhoff, E = 2 MPa, nu = 0.48, clamped along its base; 0.014 N pressed down on each of its nine central nodes."

"#,
    cornea_organ!("stvk"),
    r#"[[organs.loads]]                     # the nine central nodes of the anterior surface (apex z = 2.53 mm)
kind = "force"
region = { box = { min = [-0.55e-3, -0.55e-3, 2.45e-3], max = [0.55e-3, 0.55e-3, 2.65e-3] } }
force = [0.0, 0.0, -0.126]           # N in all: 0.014 N on each node (seed 001, section 6.1)

[[tools]]
kind = "probe"
name = "probe"
radius = 1.0e-3

[effects]
deformation = "large"                # ANM-POD lattice scaling the PGD contact force

[fidelity]
locking = "none"

[fidelity.large]
positions = 9
max_force = 0.126                    # N, the seed's pinch
load_steps = 6
"#
);

const STRETCH: &str = r#"# Seed 004, Table 5.2, by the meshless solver: a soft cube stretched by 20 %.
[scene]
name = "stretch"
description = "A 0.1 m cube of brain-like neo-Hookean material (E = 3000 Pa, nu = 0.49), face y = 0 clamped, face y = 0.1 m pulled 0.02 m with its x and z motion fixed; solved by element-free Galerkin with adaptive dynamic relaxation (13^3 nodes). Abaqus (seed 004, 17,576 nodes): 0.06477 J, 6.109 N."

[[organs]]
name = "cube"
density = 1000.0

[organs.mesh]
builtin = "block"
size = [0.1, 0.1, 0.1]
divisions = [12, 12, 12]
cell = "hex8"

[[organs.materials]]
model = "neo_hookean"
young = 3000.0
poisson = 0.49

[organs.fixed]
box = { min = [0.0, 0.0, 0.0], max = [0.1, 0.0, 0.1] }

[organs.accessible]
half_space = { point = [0.0, 0.0, 0.1], normal = [0.0, 0.0, 1.0] }

[[organs.loads]]
kind = "displacement"
name = "pulled"
region = { box = { min = [0.0, 0.1, 0.0], max = [0.1, 0.1, 0.1] } }
x = 0.0
y = 0.02
z = 0.0

[[tools]]                            # `vademecum run` palpates the top
kind = "probe"
name = "probe"
radius = 0.01

[fidelity]
solver = "meshless"
"#;

const PATCH_CUT: &str = concat!(
    r#"# Seed 000, section 3.5.1: the patch model with its cut.
[scene]
name = "patch_cut"
description = "The patch of seed 000, section 3.5.1 (5 x 5 unit hexahedra one cell deep, E = 5 Pa, nu = 0.3, one base corner fixed, the base sliding horizontally) with a straight surface cut down the plane x = 4 through the top cell row (two nodes on the front face), opened by 1 N down on the upper corner node; solved by XFEM (cracking nodes)."

"#,
    patch_organ!(),
    r#"[[organs.cuts]]                      # the blade goes down x = 4 through the top cell row
blade = [[[4.0, -0.1, 5.1], [4.0, 1.1, 5.1]], [[4.0, -0.1, 3.95], [4.0, 1.1, 3.95]]]

[[tools]]
kind = "scalpel"
name = "scalpel"
blade_length = 1.2
cut_force = 1.0                      # N (the seed's unit threshold, section 3.4)

[effects]
cutting = true

[fidelity]
locking = "none"
"#
);

const KERATOTOMY: &str = concat!(
    r#"# Seed 000, section 3.5.2: radial keratotomy, four radial incisions in a linear cornea.
[scene]
name = "keratotomy"
description = "The cornea dome of seed 000, section 3.5.2 (radius of curvature 7.8 mm, 11.5 mm across, 0.55 mm thick; 24 x 24 x 3 hexahedra instead of the seed's 6,840, which is not available), linear, E = 2 MPa, nu = 0.48, clamped along its base, under an intraocular pressure of 2 kPa (15 mmHg); four radial incisions from 1.5 to 4.5 mm off the apex, 70 % of the thickness deep, solved by XFEM (cracking nodes)."

"#,
    cornea_organ!("linear"),
    r#"[[organs.loads]]                     # intraocular pressure on the posterior surface
kind = "pressure"
region = { group = "posterior" }
pressure = 2000.0                    # Pa

[[organs.cuts]]                       # radial incision along +x, 1.5 -> 4.5 mm from the apex, 70 % deep
blade = [
  [[1.5192e-03, 0.0, 2.4821e-03], [1.4260e-03, 0.0, 2.0062e-03]],
  [[2.0256e-03, 0.0, 2.3655e-03], [1.9013e-03, 0.0, 1.8967e-03]],
  [[2.5321e-03, 0.0, 2.2128e-03], [2.3766e-03, 0.0, 1.7534e-03]],
  [[3.0385e-03, 0.0, 2.0219e-03], [2.8519e-03, 0.0, 1.5742e-03]],
  [[3.5449e-03, 0.0, 1.7896e-03], [3.3272e-03, 0.0, 1.3562e-03]],
  [[4.0513e-03, 0.0, 1.5117e-03], [3.8026e-03, 0.0, 1.0953e-03]],
  [[4.5577e-03, 0.0, 1.1823e-03], [4.2779e-03, 0.0, 7.8612e-04]],
]

[[organs.cuts]]                       # radial incision along +y, 1.5 -> 4.5 mm from the apex, 70 % deep
blade = [
  [[0.0, 1.5192e-03, 2.4821e-03], [0.0, 1.4260e-03, 2.0062e-03]],
  [[0.0, 2.0256e-03, 2.3655e-03], [0.0, 1.9013e-03, 1.8967e-03]],
  [[0.0, 2.5321e-03, 2.2128e-03], [0.0, 2.3766e-03, 1.7534e-03]],
  [[0.0, 3.0385e-03, 2.0219e-03], [0.0, 2.8519e-03, 1.5742e-03]],
  [[0.0, 3.5449e-03, 1.7896e-03], [0.0, 3.3272e-03, 1.3562e-03]],
  [[0.0, 4.0513e-03, 1.5117e-03], [0.0, 3.8026e-03, 1.0953e-03]],
  [[0.0, 4.5577e-03, 1.1823e-03], [0.0, 4.2779e-03, 7.8612e-04]],
]

[[organs.cuts]]                       # radial incision along -x, 1.5 -> 4.5 mm from the apex, 70 % deep
blade = [
  [[-1.5192e-03, 0.0, 2.4821e-03], [-1.4260e-03, 0.0, 2.0062e-03]],
  [[-2.0256e-03, 0.0, 2.3655e-03], [-1.9013e-03, 0.0, 1.8967e-03]],
  [[-2.5321e-03, 0.0, 2.2128e-03], [-2.3766e-03, 0.0, 1.7534e-03]],
  [[-3.0385e-03, 0.0, 2.0219e-03], [-2.8519e-03, 0.0, 1.5742e-03]],
  [[-3.5449e-03, 0.0, 1.7896e-03], [-3.3272e-03, 0.0, 1.3562e-03]],
  [[-4.0513e-03, 0.0, 1.5117e-03], [-3.8026e-03, 0.0, 1.0953e-03]],
  [[-4.5577e-03, 0.0, 1.1823e-03], [-4.2779e-03, 0.0, 7.8612e-04]],
]

[[organs.cuts]]                       # radial incision along -y, 1.5 -> 4.5 mm from the apex, 70 % deep
blade = [
  [[0.0, -1.5192e-03, 2.4821e-03], [0.0, -1.4260e-03, 2.0062e-03]],
  [[0.0, -2.0256e-03, 2.3655e-03], [0.0, -1.9013e-03, 1.8967e-03]],
  [[0.0, -2.5321e-03, 2.2128e-03], [0.0, -2.3766e-03, 1.7534e-03]],
  [[0.0, -3.0385e-03, 2.0219e-03], [0.0, -2.8519e-03, 1.5742e-03]],
  [[0.0, -3.5449e-03, 1.7896e-03], [0.0, -3.3272e-03, 1.3562e-03]],
  [[0.0, -4.0513e-03, 1.5117e-03], [0.0, -3.8026e-03, 1.0953e-03]],
  [[0.0, -4.5577e-03, 1.1823e-03], [0.0, -4.2779e-03, 7.8612e-04]],
]

[[tools]]
kind = "scalpel"
name = "diamond knife"
blade_length = 1.0e-3                # m
cut_force = 0.02                     # N (no measured value; the seed takes a unit threshold, section 3.4): below the 0.035-0.065 N the model gives the blade of the built-in incision

[effects]
cutting = true

[fidelity]
locking = "bbar"
"#
);

/// The unit cube of seed 000 §4.6.1 (one hexahedron, E = 5 Pa, ν = 0.3), with the damage
/// parameters `$alpha`, `$beta`.
macro_rules! unit_cube {
    ($alpha:literal, $beta:literal) => {
        concat!(
            r#"[[organs]]
name = "cube"
density = 1.0

[organs.mesh]
builtin = "block"
origin = [0.0, 0.0, 0.0]
size = [1.0, 1.0, 1.0]
divisions = [1, 1, 1]
cell = "hex8"

[[organs.materials]]
model = "linear"
young = 5.0                          # Pa
poisson = 0.3
damage = { alpha = "#,
            $alpha,
            ", beta = ",
            $beta,
            r#" }

[organs.accessible]
half_space = { point = [0.0, 0.0, 1.0], normal = [0.0, 0.0, 1.0] }

"#
        )
    };
}

/// The grasper, effects and fidelity of the two seed cubes, up to `[fidelity.tearing]`.
macro_rules! cube_tool_and_fidelity {
    () => {
        r#"[[tools]]
kind = "grasper"
name = "grasper"
jaw_width = 0.2                      # m
max_force = 1.0                      # N

[effects]
tearing = true

[fidelity]
locking = "none"                     # the seed's standard hexahedron

[fidelity.tearing]
"#
    };
}

const CUBE_TEAR: &str = concat!(
    r#"# Seed 000, section 4.6.1.1: a unit cube pulled at an upper corner until it damages.
[scene]
name = "cube_tear"
description = "The unit cube of seed 000, section 4.6.1.1: one hexahedron, E = 5 Pa, nu = 0.3, Simo damage with alpha = beta = 0.4; one base node fixed, the other base nodes sliding in the base plane, and the base node at (1, 0, 0) also held in y (the least constraint that removes the free rotation about z, which the seed leaves); the upper corner (1, 1, 1) pulled up by 0.05 N per step for 10 steps; 3 POD vectors. The grasper may also take the three other upper corners (grasp_sites = 4), each pulled off the cube along its outward normal."

"#,
    unit_cube!("0.4", "0.4"),
    r#"[organs.fixed]                       # the fully fixed base node
sphere = { center = [0.0, 0.0, 0.0], radius = 0.01 }

[[organs.loads]]                     # the base slides in its plane
kind = "displacement"
name = "base"
region = { box = { min = [0.0, 0.0, 0.0], max = [1.0, 1.0, 0.0] } }
z = 0.0

[[organs.loads]]                     # stops the rotation about z
kind = "displacement"
name = "anchor"
region = { sphere = { center = [1.0, 0.0, 0.0], radius = 0.01 } }
y = 0.0

[[organs.loads]]                     # per pseudo-time step
kind = "point"
at = [1.0, 1.0, 1.0]
force = [0.0, 0.0, 0.05]             # N

"#,
    cube_tool_and_fidelity!(),
    r#"schedule = [{ steps = 10, scale = 1.0 }]
pod_vectors = 3
grasp_sites = 4                      # the scene's corner and the three other upper corners
"#
);

const CUBE_SHEAR: &str = concat!(
    r#"# Seed 000, section 4.6.1.2: a unit cube in cyclic shear.
[scene]
name = "cube_shear"
description = "The unit cube of seed 000, section 4.6.1.2: one hexahedron, E = 5 Pa, nu = 0.3, Simo damage with alpha = 0.4, beta = 0.1; base fixed; the four upper nodes pushed along x by 0.004 N each per step, in the seed's cyclic schedule of 200 steps (25 steps up, 25 back, with increments 0.004, 0.008, 0.012, 0.016 N)."

"#,
    unit_cube!("0.4", "0.1"),
    r#"[organs.fixed]                       # the base
box = { min = [0.0, 0.0, 0.0], max = [1.0, 1.0, 0.0] }

[[organs.loads]]                     # 0.004 N on each upper node per unit step
kind = "force"
region = { box = { min = [0.0, 0.0, 1.0], max = [1.0, 1.0, 1.0] } }
force = [0.016, 0.0, 0.0]            # N, shared equally by the four nodes

"#,
    cube_tool_and_fidelity!(),
    r#"schedule = [
  { steps = 25, scale = 1.0 }, { steps = 25, scale = -1.0 },
  { steps = 25, scale = 2.0 }, { steps = 25, scale = -2.0 },
  { steps = 25, scale = 3.0 }, { steps = 25, scale = -3.0 },
  { steps = 25, scale = 4.0 }, { steps = 25, scale = -4.0 },
]
"#
);

const GALLBLADDER_FAT: &str = r#"# Seed 000, section 4.6.2: tearing the fat off a gallbladder.
[scene]
name = "gallbladder_fat"
description = "Seed 000, section 4.6.2 on the sofa_env gallbladder (tetrahedra, 866 nodes; the seed's hexahedral Calot's-triangle model is not available): a 9 mm layer of fat on its upper side (274 tetrahedra; E = 0.5 MPa, nu = 0.495, Simo damage with beta = 0 as the seed, alpha = 300 sqrt(Pa) where the seed prints alpha = 1 without units, see docs/tearing.md), the gallbladder itself E = 1.15 kPa, nu = 0.48 and never damaged; its underside (where it lies on the liver) and the two ends of the fat (where it joins the connective tissue) fixed; grasped at the middle of the fat and pulled up by 1/3 N per step for 15 steps: the fat under the jaws passes the 0.8 damage threshold at step 14 (4.7 N) of the full-order reference; a session's grasper tears it at about 6.7 N (docs/tearing.md). Reads ../shared/data (run from the repository's folder or below it)."

[[organs]]
name = "gallbladder"
density = 1000.0

[organs.mesh]
file = "../shared/data/meshes/derived/sofa_env_gallbladder_tet_h5.msh"
scale = 0.001                        # mm -> m

[[organs.materials]]                 # the gallbladder wall and bile
model = "linear"
young = 1150.0                       # Pa
poisson = 0.48

[[organs.materials]]                 # the fat: every cell above z = -9.1 mm
within = { half_space = { point = [0.0, 0.0, -0.0091], normal = [0.0, 0.0, 1.0] } }
model = "linear"
young = 0.5e6                        # Pa
poisson = 0.495
damage = { alpha = 300.0, beta = 0.0 }   # alpha in sqrt(Pa), like the equivalent strain

[[organs.fixed]]                     # the underside, on the liver
name = "liver"
region = { half_space = { point = [0.0, 0.0, -0.0275], normal = [0.0, 0.0, -1.0] } }

[[organs.fixed]]                     # the fat's end towards the fundus
name = "fundus_end"
region = { box = { min = [-1.0, -1.0, -0.0091], max = [-0.051, 1.0, 1.0] } }

[[organs.fixed]]                     # the fat's end towards the cystic duct
name = "duct_end"
region = { box = { min = [-0.015, -1.0, -0.0091], max = [1.0, 1.0, 1.0] } }

[organs.accessible]
half_space = { point = [0.0, 0.0, -0.0091], normal = [0.0, 0.0, 1.0] }

[[organs.loads]]                     # the grasp: 1/3 N up per step, shared by the nodes under the jaws
kind = "force"
region = { sphere = { center = [-0.03302, -0.00284, -0.00012], radius = 0.003 } }
force = [0.0, 0.0, 0.3333333333333333]   # N

[[tools]]
kind = "grasper"
name = "grasper"
jaw_width = 0.006                    # m
max_force = 8.0                      # N: the session's fat tears at about 6.7 N (docs/tearing.md)

[effects]
tearing = true

[fidelity.tearing]
schedule = [{ steps = 15, scale = 1.0 }]
pod_vectors = 3                      # as the seed
"#;

const LIVER_CUT: &str = r#"# Seed 003: co-rotational cutting of SOFA's liver, drawn with its smooth visual mesh.
[scene]
name = "liver_cut"
description = "SOFA's liver (181 nodes, 596 tetrahedra; 6.5 x 4.9 x 4.4 cm) with its smooth visual surface (2,194 vertices) embedded in it, E = 8 kPa, nu = 0.45, held along its back under gravity, its left lobe drawn aside by a 0.15 N retractor; a scalpel with a 3.2 cm edge cuts 2.8 cm into the front in the plane x = -2.02 cm. Co-rotational XFEM (seed 003) at the frame rate, the visual surface split along the cut. Reads ../shared/data (run from the repository's folder or below it)."

[[organs]]
name = "liver"
density = 1060.0

[organs.mesh]
file = "../shared/data/meshes/sofa/liver.msh"
scale = 0.01                         # the mesh is in cm

[organs.visual]                      # same units as the mesh: its scale applies
file = "../shared/data/meshes/sofa/liver-smooth.obj"

[[organs.materials]]
model = "linear"
young = 8e3
poisson = 0.45

[organs.fixed]                       # the back, where the liver lies against the diaphragm
half_space = { point = [0.0, 0.0, -0.01], normal = [0.0, 0.0, -1.0] }

[organs.accessible]                  # the front, where the blade works
half_space = { point = [0.0, 0.0, 0.01], normal = [0.0, 0.0, 1.0] }

[[organs.loads]]
kind = "gravity"
acceleration = [0.0, -9.81, 0.0]

[[organs.loads]]                     # a retractor drawing the left lip aside
kind = "point"
at = [-0.030, 0.025, 0.024]          # nearest node
force = [-0.15, 0.0, 0.0]            # N

[[organs.cuts]]                      # the blade's edge upright, pushed from the front into the liver
blade = [
  [[-0.0202, 0.010, 0.032], [-0.0202, 0.042, 0.032]],
  [[-0.0202, 0.010, 0.025], [-0.0202, 0.042, 0.025]],
  [[-0.0202, 0.010, 0.018], [-0.0202, 0.042, 0.018]],
  [[-0.0202, 0.010, 0.011], [-0.0202, 0.042, 0.011]],
  [[-0.0202, 0.010, 0.004], [-0.0202, 0.042, 0.004]],
]

[[tools]]
kind = "scalpel"
name = "scalpel"
blade_length = 0.04                  # m
cut_force = 0.05                     # N

[effects]
cutting = true

[fidelity]
cutting = "corotational_xfem"
"#;
