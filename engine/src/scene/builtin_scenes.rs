//! Scenes compiled into the binary, so defaults need no files.

/// Names of the built-in scenes; the first is the default.
pub const BUILTIN_NAMES: [&str; 7] = ["organ", "patch", "cantilever", "cornea", "stretch", "patch_cut", "keratotomy"];

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
    r#"[fidelity]
locking = "none"
"#
);

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
