//! The pipeline configurations the quality harness compares: every registered pipeline at its
//! defaults with one- and two-pixel points, the automatic parameters' sweeps, and the variants
//! made for one scene (the filters' transparency, and the filters' and the pyramid's shadows)
//! or for a method's own choice (the surfels' modes, the triangulation's fan normals).

use strata_viewer::pipelines::{PipelineInfo, REGISTRY};

/// One pipeline configuration of the comparison.
pub struct Config {
    pub pipeline: &'static PipelineInfo,
    pub setting: String,
    pub point_size: f32,
    /// An automatic parameter set to a multiple of its automatic value.
    pub auto_factor: Option<(&'static str, f32)>,
    /// Parameters set to values (`--set NAME=VALUE`); none at the defaults.
    pub fixed: &'static [(&'static str, f32)],
}

impl Config {
    pub fn fixed(&self, name: &str) -> Option<f32> {
        self.fixed.iter().find(|(n, _)| *n == name).map(|(_, v)| *v)
    }

    /// Layers and opacity of a configuration that peels and blends layers: scored against
    /// the mesh peeled and blended the same way, on the nested layers scene only.
    pub fn peeled(&self) -> Option<(u32, f32)> {
        Some((self.fixed("layers")? as u32, self.fixed("opacity")?))
    }

    pub fn shadowed(&self) -> bool {
        self.fixed("shadows").is_some_and(|s| s > 0.0)
    }

    /// The direction towards the light a shadowed configuration sets.
    pub fn light(&self) -> glam::Vec3 {
        let axis = |name| self.fixed(name).unwrap_or(0.0);
        glam::Vec3::new(axis("light.x"), axis("light.y"), axis("light.z"))
    }

    /// The lighting its picture is scored under: a shadowed configuration's light fixed in the
    /// world, with the mesh's shadows, replaces the pipeline's own.
    pub fn lighting_name(&self) -> &'static str {
        if self.shadowed() {
            "directional Blinn-Phong with shadows"
        } else {
            self.pipeline.lighting.name()
        }
    }

    /// The scene a variant is made for; `None`: every scene.
    pub fn scene(&self) -> Option<&'static str> {
        if self.peeled().is_some() {
            Some(LAYERS_SCENE)
        } else if self.shadowed() {
            Some(SHADOW_SCENE)
        } else {
            None
        }
    }
}

/// A variant: the pipeline, its fixed parameters, the point size and the setting's label.
type Variant = (
    &'static str,
    &'static [(&'static str, f32)],
    f32,
    &'static str,
);

/// Variants compared beside each pipeline's defaults: the surfels' planar and all-curved
/// modes against their hybrid default (paper 001's Table 2), and hybrid with the paper's
/// c-surfels, each bent alike rather than by its curvature; the filters' transparency, six
/// layers at half opacity (paper 004's Figure 17); the point shadows (paper 004, section 6) in
/// the filters and carried through the pyramid's pull-push; the triangulation shaded with its
/// fans' normals (paper 002's) and the pyramid with its depth's (paper 003's), where their
/// defaults take the dataset's.
const VARIANTS: &[Variant] = &[
    (
        "pyramid",
        &[
            ("shadows", 1.0),
            ("light.x", SHADOW_LIGHT[0]),
            ("light.y", SHADOW_LIGHT[1]),
            ("light.z", SHADOW_LIGHT[2]),
        ],
        1.0,
        "shadows=1 1px",
    ),
    // The pyramid shaded with the normals it estimates from depth (paper 003's), where its
    // default takes the dataset's.
    (
        "pyramid",
        &[("stored_normals", 0.0)],
        1.0,
        "stored_normals=0",
    ),
    ("surfels", &[("mode", 0.0)], 1.0, "mode=planar"),
    ("surfels", &[("mode", 1.0)], 1.0, "mode=curved"),
    ("surfels", &[("curvature", 0.0)], 1.0, "curvature=0"),
    (
        "triangulate",
        &[("stored_normals", 0.0)],
        1.0,
        "stored_normals=0",
    ),
    (
        "filters",
        &[("layers", 6.0), ("opacity", 0.5)],
        2.0,
        "layers=6 opacity=0.5 2px",
    ),
    (
        "filters",
        &[
            ("shadows", 1.0),
            ("light.x", SHADOW_LIGHT[0]),
            ("light.y", SHADOW_LIGHT[1]),
            ("light.z", SHADOW_LIGHT[2]),
        ],
        2.0,
        "shadows=1 2px",
    ),
    // The stability sweep of the shadows: a light grazing the floor (about 15° above it, from
    // in front, so that the ball's long shadow falls on the floor in view).
    (
        "filters",
        &[
            ("shadows", 1.0),
            ("light.x", GRAZING_LIGHT[0]),
            ("light.y", GRAZING_LIGHT[1]),
            ("light.z", GRAZING_LIGHT[2]),
        ],
        2.0,
        "shadows=1 grazing 2px",
    ),
    // Soft shadows: 16 samples over a 10° light.
    (
        "filters",
        &[
            ("shadows", 2.0),
            ("shadow_samples", 16.0),
            ("light_size", 10.0),
            ("light.x", SHADOW_LIGHT[0]),
            ("light.y", SHADOW_LIGHT[1]),
            ("light.z", SHADOW_LIGHT[2]),
        ],
        2.0,
        "shadows=2 2px",
    ),
];
/// The scene the peeled variants run on, and the one the shadowed ones run on.
const LAYERS_SCENE: &str = "layers";
const SHADOW_SCENE: &str = "shadow";
/// The shadow scene's light: towards +x, -y and up; and one grazing the floor.
const SHADOW_LIGHT: [f32; 3] = [0.5, -0.3, 1.0];
const GRAZING_LIGHT: [f32; 3] = [0.25, -0.95, 0.27];

/// Every registered pipeline at its defaults with one- and two-pixel points (one-pixel only
/// where the point size does not change its picture), and, in the full
/// run, each automatic parameter at half and twice its automatic value: the sweeps come from
/// the pipelines' parameter tables.
pub fn configs(full: bool) -> Vec<Config> {
    let mut v = Vec::new();
    for &pipeline in REGISTRY {
        // A pipeline whose picture the point size does not change is measured once.
        let sizes: &[f32] = if pipeline.uses_point_size {
            &[1.0, 2.0]
        } else {
            &[1.0]
        };
        for &point_size in sizes {
            v.push(Config {
                pipeline,
                setting: format!("{point_size}px"),
                point_size,
                auto_factor: None,
                fixed: &[],
            });
        }
        for &(_, fixed, point_size, setting) in VARIANTS.iter().filter(|v| v.0 == pipeline.name) {
            v.push(Config {
                pipeline,
                setting: setting.into(),
                point_size,
                auto_factor: None,
                fixed,
            });
        }
        let automatic = pipeline.params.iter().filter(|p| p.auto.is_some());
        for spec in automatic.filter(|_| full) {
            for f in [0.5f32, 2.0] {
                v.push(Config {
                    pipeline,
                    setting: format!("{}=auto×{f}", spec.name),
                    point_size: 1.0,
                    auto_factor: Some((spec.name, f)),
                    fixed: &[],
                });
            }
        }
    }
    v
}
