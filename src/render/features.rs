//! "Simulate only the effects a scene calls for": the set of effects a scene (and the outputs
//! asked for) needs, turned into the `-D` switches of kernels/render/features.cl and of the
//! generated kernels/render/outputs.cl.

use crate::layout::outputs::{OUTPUTS, OutputSet};
use crate::scene::{MaterialKind, Scene};

/// One compile-time switch and why it is on or off.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Feature {
    /// The kernel macro, e.g. `HAS_GLASS`.
    pub define: &'static str,
    pub on: bool,
    pub why: String,
}

/// The effects compiled into the megakernel.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FeatureSet {
    pub features: Vec<Feature>,
}

fn feature(define: &'static str, on: bool, why: impl Into<String>) -> Feature {
    Feature {
        define,
        on,
        why: why.into(),
    }
}

fn count_reason(n: usize, what: &str) -> String {
    if n == 0 {
        format!("the scene has no {what}")
    } else {
        format!("{n} {what}")
    }
}

impl FeatureSet {
    /// The smallest kernel that renders `scene` with `outputs`.
    pub fn for_scene(scene: &Scene, outputs: OutputSet) -> FeatureSet {
        let surfaces_with = |pred: &dyn Fn(&crate::scene::Material) -> bool| {
            scene
                .triangles
                .iter()
                .filter(|t| pred(&scene.materials[t.material as usize]))
                .count()
                + scene
                    .spheres
                    .iter()
                    .filter(|s| pred(&scene.materials[s.material as usize]))
                    .count()
        };
        let not_emissive = |m: &crate::scene::Material| !m.is_emissive();
        let diffuse =
            surfaces_with(&|m| not_emissive(m) && matches!(m.kind, MaterialKind::Diffuse { .. }));
        let specular =
            surfaces_with(&|m| not_emissive(m) && matches!(m.kind, MaterialKind::Specular { .. }));
        let glass =
            surfaces_with(&|m| not_emissive(m) && matches!(m.kind, MaterialKind::Glass { .. }));
        let metal =
            surfaces_with(&|m| not_emissive(m) && matches!(m.kind, MaterialKind::Metal { .. }));
        let textured = surfaces_with(&|m| {
            not_emissive(m)
                && matches!(
                    m.kind,
                    MaterialKind::Diffuse {
                        texture: Some(_),
                        ..
                    }
                )
        });
        let env = scene.environment.as_ref();
        let env_textured = env.is_some_and(|e| e.texture.is_some());
        let sphere_lights = scene.emissive_sphere_count();
        let tri_lights = scene.emissive_triangle_count();
        let lens = scene.camera.lens_radius;
        let nee = scene.render.next_event_estimation;
        let rr = scene.render.russian_roulette;
        let mut features = vec![
            feature(
                "HAS_TRIANGLES",
                !scene.triangles.is_empty(),
                count_reason(scene.triangles.len(), "triangles"),
            ),
            feature(
                "HAS_SPHERES",
                !scene.spheres.is_empty(),
                count_reason(scene.spheres.len(), "spheres"),
            ),
            feature(
                "HAS_TEXTURES",
                textured > 0,
                count_reason(textured, "surfaces with a textured material"),
            ),
            feature(
                "HAS_ENV",
                env.is_some(),
                if env.is_some() {
                    "an infinite light"
                } else {
                    "no infinite light: escaping rays are black"
                },
            ),
            feature(
                "HAS_ENV_TEXTURE",
                env_textured,
                if env_textured {
                    "the infinite light has a texture"
                } else {
                    "no textured infinite light"
                },
            ),
            feature(
                "HAS_SPHERE_LIGHTS",
                sphere_lights > 0,
                count_reason(sphere_lights, "emissive spheres"),
            ),
            feature(
                "HAS_TRIANGLE_LIGHTS",
                tri_lights > 0,
                count_reason(tri_lights, "emissive triangles"),
            ),
            feature(
                "HAS_DIFFUSE",
                diffuse > 0,
                count_reason(diffuse, "diffuse surfaces"),
            ),
            feature(
                "HAS_SPECULAR",
                specular > 0,
                count_reason(specular, "mirror surfaces"),
            ),
            feature(
                "HAS_GLASS",
                glass > 0,
                count_reason(glass, "glass surfaces"),
            ),
            feature(
                "HAS_METAL",
                metal > 0,
                count_reason(metal, "metal surfaces"),
            ),
            feature(
                "HAS_DOF",
                lens > 0.0,
                if lens > 0.0 {
                    format!("lens_radius {lens}")
                } else {
                    "pinhole camera (lens_radius 0)".into()
                },
            ),
            feature(
                "HAS_RUSSIAN_ROULETTE",
                rr,
                if rr {
                    "render.russian_roulette = true"
                } else {
                    "render.russian_roulette = false: paths stop at max_depth"
                },
            ),
            feature(
                "NEXT_EVENT_ESTIMATION",
                nee,
                if nee {
                    "render.next_event_estimation = true"
                } else {
                    "render.next_event_estimation = false"
                },
            ),
        ];
        features.extend(output_switches(outputs));
        FeatureSet { features }
    }

    /// Every effect compiled in (the generic kernel). Russian roulette and light sampling are
    /// choices of estimator, not effects, so they still follow the scene: the generic kernel
    /// renders the same image.
    pub fn all_features(scene: &Scene, outputs: OutputSet) -> FeatureSet {
        let mut set = FeatureSet::for_scene(scene, outputs);
        for f in &mut set.features {
            if f.define.starts_with("HAS_") && f.define != "HAS_RUSSIAN_ROULETTE" && !f.on {
                f.on = true;
                f.why = format!("--all-features ({})", f.why);
            }
        }
        set
    }

    pub fn is_on(&self, define: &str) -> bool {
        self.features.iter().any(|f| f.define == define && f.on)
    }

    /// `-D` options for the kernel build.
    pub fn defines(&self) -> Vec<(String, String)> {
        self.features
            .iter()
            .map(|f| (f.define.to_string(), (f.on as u32).to_string()))
            .collect()
    }

    /// A short tag naming the variant, e.g. for logs: the switches that are on.
    pub fn tag(&self) -> String {
        self.features
            .iter()
            .filter(|f| f.on)
            .map(|f| f.define.trim_start_matches("HAS_").to_lowercase())
            .collect::<Vec<_>>()
            .join("+")
    }
}

/// One switch per output of src/layout/outputs.rs that has one: on when the output was asked
/// for (directly or by an output that needs it).
fn output_switches(outputs: OutputSet) -> Vec<Feature> {
    OUTPUTS
        .iter()
        .filter_map(|o| {
            let define = o.switch?;
            let on = outputs.contains(o.output);
            let why = if on {
                format!("{} requested ({})", o.name, o.doc)
            } else {
                format!("nothing reads the {} output", o.name)
            };
            Some(feature(define, on, why))
        })
        .collect()
}

/// Every switch on, scene effects and outputs, and the wide BVH: the build options of kernels
/// that do not depend on a scene (the probes of the tests, the layout test).
pub fn generic_defines() -> Vec<(String, String)> {
    let scene_switches = [
        "HAS_TRIANGLES",
        "HAS_SPHERES",
        "HAS_TEXTURES",
        "HAS_ENV",
        "HAS_ENV_TEXTURE",
        "HAS_SPHERE_LIGHTS",
        "HAS_TRIANGLE_LIGHTS",
        "HAS_DIFFUSE",
        "HAS_SPECULAR",
        "HAS_GLASS",
        "HAS_METAL",
        "HAS_DOF",
        "HAS_RUSSIAN_ROULETTE",
        "NEXT_EVENT_ESTIMATION",
    ];
    scene_switches
        .into_iter()
        .chain(OUTPUTS.iter().filter_map(|o| o.switch))
        .chain(["BVH_WIDE"])
        .map(|d| (d.to_string(), "1".to_string()))
        .chain([(
            "BVH_STACK".to_string(),
            crate::bvh::wide::MAX_BVH_STACK.to_string(),
        )])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generic_defines_cover_every_switch_a_scene_can_get() {
        let scene = crate::scene::load_scene(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell_glossy.toml"),
        )
        .unwrap();
        let generic: Vec<String> = generic_defines().into_iter().map(|d| d.0).collect();
        for f in FeatureSet::for_scene(&scene, OutputSet::colour()).features {
            assert!(generic.contains(&f.define.to_string()), "{}", f.define);
        }
        // kernels/render/features.cl refuses a build without each scene switch.
        let cl = include_str!("../../kernels/render/features.cl");
        for d in generic
            .iter()
            .filter(|d| !d.starts_with("OUTPUT_") && !d.starts_with("BVH_"))
        {
            assert!(
                cl.contains(&format!("!defined({d})")),
                "features.cl does not check {d}"
            );
        }
    }
}
