//! The OpenCL sources under `kernels/`, embedded in the binary, and the small preprocessor that
//! resolves their `#include "file.cl"` lines (OpenCL compilers are given one string, and
//! include paths are not portable between drivers).

use anyhow::{Result, bail};

/// Every kernel source file, by name.
pub const SOURCES: &[(&str, &str)] = &[
    ("layout.cl", include_str!("../kernels/layout.cl")),
    ("geometry.cl", include_str!("../kernels/geometry.cl")),
    ("vectors.cl", include_str!("../kernels/vectors.cl")),
    (
        "arrays/trace.cl",
        include_str!("../kernels/arrays/trace.cl"),
    ),
    (
        "arrays/trace_wide.cl",
        include_str!("../kernels/arrays/trace_wide.cl"),
    ),
    (
        "render/features.cl",
        include_str!("../kernels/render/features.cl"),
    ),
    (
        "render/outputs.cl",
        include_str!("../kernels/render/outputs.cl"),
    ),
    ("render/rng.cl", include_str!("../kernels/render/rng.cl")),
    (
        "render/sampling.cl",
        include_str!("../kernels/render/sampling.cl"),
    ),
    (
        "render/textures.cl",
        include_str!("../kernels/render/textures.cl"),
    ),
    (
        "render/camera.cl",
        include_str!("../kernels/render/camera.cl"),
    ),
    (
        "render/materials.cl",
        include_str!("../kernels/render/materials.cl"),
    ),
    (
        "render/lights.cl",
        include_str!("../kernels/render/lights.cl"),
    ),
    ("render/film.cl", include_str!("../kernels/render/film.cl")),
    (
        "render/bandlimit.cl",
        include_str!("../kernels/render/bandlimit.cl"),
    ),
    (
        "render/shadows.cl",
        include_str!("../kernels/render/shadows.cl"),
    ),
    (
        "render/light_field.cl",
        include_str!("../kernels/render/light_field.cl"),
    ),
    (
        "render/lens_field.cl",
        include_str!("../kernels/render/lens_field.cl"),
    ),
    (
        "render/gi_field.cl",
        include_str!("../kernels/render/gi_field.cl"),
    ),
    (
        "render/subtractive.cl",
        include_str!("../kernels/render/subtractive.cl"),
    ),
    ("render/path.cl", include_str!("../kernels/render/path.cl")),
    (
        "render/wavefront.cl",
        include_str!("../kernels/render/wavefront.cl"),
    ),
    (
        "render/pathtrace.cl",
        include_str!("../kernels/render/pathtrace.cl"),
    ),
    ("filters/ddf.cl", include_str!("../kernels/filters/ddf.cl")),
    (
        "filters/ddf_packed.cl",
        include_str!("../kernels/filters/ddf_packed.cl"),
    ),
    (
        "filters/atrous.cl",
        include_str!("../kernels/filters/atrous.cl"),
    ),
    (
        "filters/atrous_packed.cl",
        include_str!("../kernels/filters/atrous_packed.cl"),
    ),
    (
        "filters/lanes.cl",
        include_str!("../kernels/filters/lanes.cl"),
    ),
    (
        "filters/bmfr.cl",
        include_str!("../kernels/filters/bmfr.cl"),
    ),
    (
        "filters/bmfr_fit_packed.cl",
        include_str!("../kernels/filters/bmfr_fit_packed.cl"),
    ),
    (
        "filters/bmfr_apply_packed.cl",
        include_str!("../kernels/filters/bmfr_apply_packed.cl"),
    ),
    (
        "filters/bmfr_nlm.cl",
        include_str!("../kernels/filters/bmfr_nlm.cl"),
    ),
    (
        "filters/bmfr_outliers.cl",
        include_str!("../kernels/filters/bmfr_outliers.cl"),
    ),
    (
        "filters/bmfr_nlm_packed.cl",
        include_str!("../kernels/filters/bmfr_nlm_packed.cl"),
    ),
    (
        "filters/bmfr_select_packed.cl",
        include_str!("../kernels/filters/bmfr_select_packed.cl"),
    ),
    (
        "filters/bmfr_prefilter_packed.cl",
        include_str!("../kernels/filters/bmfr_prefilter_packed.cl"),
    ),
    (
        "filters/bmfr_emission.cl",
        include_str!("../kernels/filters/bmfr_emission.cl"),
    ),
    (
        "filters/bmfr_guided.cl",
        include_str!("../kernels/filters/bmfr_guided.cl"),
    ),
    (
        "filters/bmfr_guided_packed.cl",
        include_str!("../kernels/filters/bmfr_guided_packed.cl"),
    ),
    (
        "filters/aaf_pass.cl",
        include_str!("../kernels/filters/aaf_pass.cl"),
    ),
    (
        "filters/aaf_indirect.cl",
        include_str!("../kernels/filters/aaf_indirect.cl"),
    ),
    (
        "render/indirect.cl",
        include_str!("../kernels/render/indirect.cl"),
    ),
    (
        "filters/aaf_shadows.cl",
        include_str!("../kernels/filters/aaf_shadows.cl"),
    ),
    (
        "filters/sheared_common.cl",
        include_str!("../kernels/filters/sheared_common.cl"),
    ),
    (
        "filters/sheared.cl",
        include_str!("../kernels/filters/sheared.cl"),
    ),
    (
        "filters/sheared_dof.cl",
        include_str!("../kernels/filters/sheared_dof.cl"),
    ),
    (
        "filters/sheared_gi.cl",
        include_str!("../kernels/filters/sheared_gi.cl"),
    ),
    (
        "filters/sheared_lens_shadows.cl",
        include_str!("../kernels/filters/sheared_lens_shadows.cl"),
    ),
    (
        "filters/path_density.cl",
        include_str!("../kernels/filters/path_density.cl"),
    ),
    (
        "filters/stylized.cl",
        include_str!("../kernels/filters/stylized.cl"),
    ),
    (
        "bench/roofline.cl",
        include_str!("../kernels/bench/roofline.cl"),
    ),
    ("test/probes.cl", include_str!("../kernels/test/probes.cl")),
];

pub fn source(name: &str) -> Option<&'static str> {
    SOURCES.iter().find(|(n, _)| *n == name).map(|(_, s)| *s)
}

/// The complete program text for `main`: `prelude` first, then the file with every include
/// expanded once (later includes of the same file are dropped, like `#pragma once`).
/// `#line` directives keep the compiler's messages pointing at the original files and lines.
pub fn assemble(main: &str, prelude: &str) -> Result<String> {
    let mut out = String::new();
    out.push_str(prelude);
    let mut seen = Vec::new();
    expand(main, &mut out, &mut seen, 0)?;
    Ok(out)
}

fn expand(name: &str, out: &mut String, seen: &mut Vec<String>, depth: usize) -> Result<()> {
    if depth > 32 {
        bail!("kernel include nesting deeper than 32 at {name}");
    }
    if seen.iter().any(|s| s == name) {
        return Ok(());
    }
    seen.push(name.to_string());
    let Some(text) = source(name) else {
        bail!("kernel source {name:?} is not embedded (add it to src/kernels.rs)");
    };
    out.push_str(&format!("#line 1 \"{name}\"\n"));
    for (i, line) in text.lines().enumerate() {
        let trimmed = line.trim_start();
        if let Some(rest) = trimmed.strip_prefix("#include") {
            let inc = rest.trim().trim_matches('"');
            expand(inc, out, seen, depth + 1)?;
            out.push_str(&format!("#line {} \"{name}\"\n", i + 2));
        } else {
            out.push_str(line);
            out.push('\n');
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_include_resolves_and_each_file_appears_once() {
        let text = assemble("render/pathtrace.cl", "").unwrap();
        let count = text.matches("#line 1 \"arrays/trace.cl\"").count();
        assert_eq!(count, 1);
        assert!(text.contains("__kernel void render"));
        assert!(!text.contains("#include"));
    }

    #[test]
    fn every_kernel_file_is_embedded() {
        fn walk(dir: &std::path::Path, root: &std::path::Path, out: &mut Vec<String>) {
            for e in std::fs::read_dir(dir).unwrap().flatten() {
                let p = e.path();
                if p.is_dir() {
                    walk(&p, root, out);
                } else if p.extension().is_some_and(|x| x == "cl") {
                    out.push(
                        p.strip_prefix(root)
                            .unwrap()
                            .to_string_lossy()
                            .replace('\\', "/"),
                    );
                }
            }
        }
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("kernels");
        let mut files = Vec::new();
        walk(&root, &root, &mut files);
        for f in &files {
            assert!(
                source(f).is_some(),
                "kernels/{f} is not in SOURCES (src/kernels.rs)"
            );
        }
        assert_eq!(files.len(), SOURCES.len());
    }

    #[test]
    fn unknown_include_is_an_error() {
        assert!(assemble("nonexistent.cl", "").is_err());
    }
}
