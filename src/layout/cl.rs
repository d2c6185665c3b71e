//! The OpenCL text generated from the Rust declarations: `kernels/layout.cl` (constants, every
//! shared struct, the float lane of every field of the per-pixel structs) and
//! `kernels/render/outputs.cl` (the megakernel's output buffer parameters and the checks of
//! its output switches, from [`super::outputs`]). Both files are committed;
//! `tests/layout.rs` regenerates them and fails when they are stale.

use std::fmt::Write as _;

use super::outputs::{BUFFERS, OUTPUTS};
use super::*;

/// One shared struct as the generator and the layout test see it.
pub struct Declaration {
    pub name: &'static str,
    /// The OpenCL C `typedef struct`.
    pub cl: String,
    pub fields: Vec<FieldLayout>,
    pub size: usize,
    /// Kernels address this struct as an array of floats (`vload16(pixel, f)`), so a
    /// `#define` gives the float lane of each field: no offset is written by hand in a kernel.
    pub lanes: bool,
}

fn declaration<T: DeviceStruct>(lanes: bool) -> Declaration {
    Declaration {
        name: T::NAME,
        cl: T::cl_declaration(),
        fields: T::fields(),
        size: T::size(),
        lanes,
    }
}

/// Every shared struct, for the generated header and the layout test.
pub fn all_declarations() -> Vec<Declaration> {
    vec![
        declaration::<SceneParams>(false),
        declaration::<BvhNode>(false),
        declaration::<WideBvhNode>(false),
        declaration::<TrianglePack>(false),
        declaration::<TriangleGeom>(false),
        declaration::<TriangleShading>(false),
        declaration::<Sphere>(false),
        declaration::<Material>(false),
        declaration::<TextureInfo>(false),
        declaration::<Light>(false),
        declaration::<FilterVector>(true),
        declaration::<WelfordSums>(true),
        declaration::<WelfordState>(true),
        declaration::<DepthShift>(true),
        declaration::<DdfParams>(false),
        declaration::<SampleVector>(true),
        declaration::<AtrousParams>(false),
        declaration::<ShadowTerms>(true),
        declaration::<ShadowPixel>(true),
        declaration::<LightFieldPixel>(true),
        declaration::<LensShadowPixel>(true),
        declaration::<IndirectPixel>(true),
        declaration::<AafShadowParams>(false),
        declaration::<ShearedParams>(false),
        declaration::<AafIndirectParams>(false),
    ]
}

/// `FilterVector` → `FILTER_VECTOR`.
pub fn upper_snake(camel: &str) -> String {
    let mut out = String::new();
    for (i, c) in camel.chars().enumerate() {
        if c.is_ascii_uppercase() && i > 0 {
            out.push('_');
        }
        out.push(c.to_ascii_uppercase());
    }
    out
}

/// The lane macros of a struct: (name, float index), plus `<STRUCT>_FLOATS`.
pub fn lane_defines(d: &Declaration) -> Vec<(String, usize)> {
    let prefix = upper_snake(d.name);
    let mut v: Vec<(String, usize)> = d
        .fields
        .iter()
        .filter(|f| !f.name.starts_with("pad"))
        .map(|f| {
            (
                format!("{prefix}_{}", f.name.to_ascii_uppercase()),
                f.offset / 4,
            )
        })
        .collect();
    v.push((format!("{prefix}_FLOATS"), d.size / 4));
    v
}

/// Constants shared by host and kernels, emitted as `#define`s: (name, OpenCL literal, comment).
pub fn shared_constants() -> Vec<(&'static str, String, &'static str)> {
    let u = |v: u32| format!("{v}u");
    vec![
        (
            "MATERIAL_DIFFUSE",
            u(MATERIAL_DIFFUSE),
            "Lambertian, Alg. 5",
        ),
        (
            "MATERIAL_SPECULAR",
            u(MATERIAL_SPECULAR),
            "perfect mirror, eq. 4.7",
        ),
        (
            "MATERIAL_GLASS",
            u(MATERIAL_GLASS),
            "Schlick Fresnel + Snell, eqs. 4.8-4.10",
        ),
        (
            "MATERIAL_METAL",
            u(MATERIAL_METAL),
            "normalised Phong lobe around the mirror direction",
        ),
        (
            "MATERIAL_EMITTER",
            u(MATERIAL_EMITTER),
            "a light surface: emits, reflects nothing",
        ),
        ("LIGHT_SPHERE", u(LIGHT_SPHERE), ""),
        ("LIGHT_TRIANGLE", u(LIGHT_TRIANGLE), ""),
        (
            "LEAF_COUNT_SHIFT",
            u(LEAF_COUNT_SHIFT),
            "BvhNode.leaf = first | count << LEAF_COUNT_SHIFT",
        ),
        ("LEAF_FIRST_MASK", format!("{LEAF_FIRST_MASK:#x}u"), ""),
        (
            "BVH_WIDTH",
            u(BVH_WIDTH),
            "children of a WideBvhNode at most",
        ),
        (
            "SKY_DEPTH",
            format!("{SKY_DEPTH:e}f"),
            "depth of a camera ray that escapes (§6.3.4)",
        ),
    ]
}

fn banner(s: &mut String, file: &str, source: &str) {
    let _ = writeln!(
        s,
        "// GENERATED from {source} by `NOISEFREE_BLESS=1 cargo test --test layout`."
    );
    let _ = writeln!(
        s,
        "// Do not edit: change {source} instead. tests/layout.rs checks that {file}"
    );
    s.push_str("// is current and that the device lays every struct out exactly as Rust does.\n");
}

/// The text of `kernels/layout.cl`.
pub fn generated_layout_cl() -> String {
    let mut s = String::new();
    banner(&mut s, "this file", "src/layout/mod.rs");
    s.push_str("#ifndef NOISEFREE_LAYOUT_CL\n#define NOISEFREE_LAYOUT_CL\n\n");
    for (name, value, doc) in shared_constants() {
        if doc.is_empty() {
            let _ = writeln!(s, "#define {name} {value}");
        } else {
            let _ = writeln!(s, "#define {name} {value} // {doc}");
        }
    }
    for d in all_declarations() {
        s.push('\n');
        s.push_str(&d.cl);
        if d.lanes {
            let _ = writeln!(s, "// Float lanes of {} (offset / 4).", d.name);
            for (name, lane) in lane_defines(&d) {
                let _ = writeln!(s, "#define {name} {lane}");
            }
        }
    }
    s.push_str("\n#endif\n");
    s
}

/// The text of `kernels/render/outputs.cl`: the output buffers as kernel parameters, in the
/// order the host binds them, and the checks that every output switch was given and that an
/// output's prerequisites are on.
pub fn generated_outputs_cl() -> String {
    let mut s = String::new();
    banner(&mut s, "this file", "src/layout/outputs.rs");
    s.push_str("#ifndef NOISEFREE_OUTPUTS_CL\n#define NOISEFREE_OUTPUTS_CL\n\n");
    s.push_str("// Every output buffer of the megakernel, one parameter each, in table order. A\n");
    s.push_str("// buffer whose output is off is bound to a one-element stand-in.\n");
    let params: Vec<String> = BUFFERS
        .iter()
        .map(|b| format!("__global float* {}", b.name))
        .collect();
    let _ = writeln!(s, "#define RENDER_OUTPUT_PARAMS {}", params.join(", "));
    let args: Vec<&str> = BUFFERS.iter().map(|b| b.name).collect();
    let _ = writeln!(s, "#define RENDER_OUTPUT_ARGS {}", args.join(", "));
    s.push('\n');
    let switches: Vec<&str> = OUTPUTS.iter().filter_map(|o| o.switch).collect();
    let missing: Vec<String> = switches
        .iter()
        .map(|sw| format!("!defined({sw})"))
        .collect();
    let _ = writeln!(s, "#if {}", missing.join(" || "));
    s.push_str(
        "#error \"noisefree: an output switch is missing from the build options\"\n#endif\n",
    );
    for o in OUTPUTS {
        let Some(sw) = o.switch else { continue };
        for r in o.requires {
            if let Some(rs) = r.decl().switch {
                let _ = writeln!(
                    s,
                    "#if {sw} && !{rs}\n#error \"noisefree: {sw} needs {rs} ({} needs {})\"\n#endif",
                    o.name,
                    r.decl().name
                );
            }
        }
    }
    s.push_str("\n#endif\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sky_depth_literal_round_trips() {
        let lit = shared_constants()
            .into_iter()
            .find(|c| c.0 == "SKY_DEPTH")
            .unwrap()
            .1;
        assert_eq!(lit.trim_end_matches('f').parse::<f32>().unwrap(), SKY_DEPTH);
    }

    #[test]
    fn lanes_of_the_filter_vector() {
        let d = declaration::<FilterVector>(true);
        let lanes = lane_defines(&d);
        let get = |n: &str| lanes.iter().find(|l| l.0 == n).unwrap().1;
        assert_eq!(get("FILTER_VECTOR_DIRECT"), 0);
        assert_eq!(get("FILTER_VECTOR_INDIRECT"), 3);
        assert_eq!(get("FILTER_VECTOR_DEPTH"), 6);
        assert_eq!(get("FILTER_VECTOR_ALBEDO2"), 13);
        assert_eq!(get("FILTER_VECTOR_FLOATS"), 16);
        assert_eq!(upper_snake("WelfordState"), "WELFORD_STATE");
    }
}
