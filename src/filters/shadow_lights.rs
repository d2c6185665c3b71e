//! Which sphere lights a shadow filter works on: the `light` and `light_count` settings that
//! aaf-shadows, sheared (effect = shadows) and stylized-shadows share. Each filters (or
//! stylizes) its lights one at a time, each on its own plane of the shadow output
//! (src/render/shadows, at most [`MAX_SHADOW_PLANES`]): `light = auto` takes the scene's first
//! `light_count` sphere lights (0: all of them, capped at the planes), a number that light
//! alone, -1 none.

use anyhow::{Result, bail};

use super::Auto;
use crate::layout::outputs::{MAX_SHADOW_PLANES, Output, OutputSet};
use crate::render::{LightPlanes, SceneInfo};

/// A shadow filter's `light` setting: a sphere light's number from 0, -1 for none, or auto.
pub fn check_light(light: Auto<i32>) -> Result<()> {
    if let Auto::Set(l) = light
        && l < -1
    {
        bail!("light is a sphere light's number from 0, or -1 for none; got {l}");
    }
    Ok(())
}

/// `light` and `light_count` together: `light` as [`check_light`], `light_count` at most the
/// shadow output's planes (`verb`: what the filter does to a light, "filtered").
pub fn check_lights(light: Auto<i32>, light_count: u32, verb: &str) -> Result<()> {
    check_light(light)?;
    if light_count > MAX_SHADOW_PLANES {
        bail!(
            "light_count: at most {MAX_SHADOW_PLANES} sphere lights are {verb} at once (one \
             plane of the shadow output each), got {light_count}"
        );
    }
    Ok(())
}

/// The sphere light a `light` setting names, if any (`auto` counts as the first).
pub fn light_index(light: Auto<i32>) -> Option<u32> {
    let l = light.or(0);
    (l >= 0).then_some(l as u32)
}

/// The sphere lights chosen, in increasing order: `light` alone when set (none for -1), else
/// the first `light_count` (after specialisation the scene's count; before it, 0 counts as the
/// first light alone).
pub fn chosen_lights(light: Auto<i32>, light_count: u32) -> Vec<u32> {
    match light {
        Auto::Auto => (0..light_count.max(1)).collect(),
        Auto::Set(_) => light_index(light).into_iter().collect(),
    }
}

/// The shadow output's planes for `lights` (light 0's one plane when there is none: the
/// sampling of a render that filters nothing still has to be valid).
pub fn light_planes(lights: &[u32]) -> LightPlanes {
    if lights.is_empty() {
        LightPlanes::one(0)
    } else {
        LightPlanes::of(lights)
    }
}

/// `lights` with their centre and radius in `scene`; an error naming `filter` and the light
/// when the scene lacks one.
pub fn lights_of(filter: &str, lights: &[u32], scene: &SceneInfo) -> Result<Vec<(u32, [f32; 4])>> {
    lights
        .iter()
        .map(|&l| match scene.sphere_lights.get(l as usize) {
            Some(c) => Ok((l, *c)),
            None => bail!(
                "the {filter} filter is set to sphere light {l}, but the scene has {} sphere \
                 light(s)",
                scene.sphere_lights.len()
            ),
        })
        .collect()
}

/// What a shadow filter reads: the shadow output when its `light` names one, else colour.
pub fn light_needs(light: Auto<i32>) -> OutputSet {
    match light_index(light) {
        Some(_) => OutputSet::of(&[Output::Colour, Output::Shadows]),
        None => OutputSet::colour(),
    }
}

/// `light = auto` becomes the first sphere light, or none when the scene has none; one note
/// per decision, and one naming the light.
pub fn specialise_light(light: &mut Auto<i32>, scene: &SceneInfo) -> Vec<String> {
    let count = scene.sphere_lights.len();
    let mut notes = Vec::new();
    if light.is_auto() {
        let l = if count > 0 { 0 } else { -1 };
        *light = Auto::Set(l);
        notes.push(if count > 0 {
            format!("light = 0: the first of {count} sphere light(s)")
        } else {
            "light = -1: the scene has no sphere light, nothing to filter (the image \
             passes through)"
                .to_string()
        });
    }
    if let Some(l) = light_index(*light) {
        match scene.sphere_lights.get(l as usize) {
            Some(c) => notes.push(format!(
                "filters sphere light {l}: centre ({}, {}, {}), radius {}",
                c[0], c[1], c[2], c[3]
            )),
            None => notes.push(format!(
                "sphere light {l} does not exist (the scene has {count}): preparing fails"
            )),
        }
    }
    notes
}

/// `light = auto` becomes the scene's first `light_count` sphere lights (all of them when 0,
/// at most [`MAX_SHADOW_PLANES`]: `light_count` is set to the number taken), or none when the
/// scene has none; a set `light` is checked against the scene ([`specialise_light`]). The
/// notes say how many lights, `how` (what each light gets, e.g. "each with its own 1-D
/// passes"), and which lights the cap leaves as rendered.
pub fn specialise_lights(
    light: &mut Auto<i32>,
    light_count: &mut u32,
    scene: &SceneInfo,
    verb: &str,
    how: &str,
) -> Vec<String> {
    let count = scene.sphere_lights.len() as u32;
    if !light.is_auto() || count == 0 {
        return specialise_light(light, scene);
    }
    let all = if *light_count == 0 {
        count
    } else {
        (*light_count).min(count)
    };
    let n = all.min(MAX_SHADOW_PLANES);
    *light_count = n;
    let mut notes = vec![format!(
        "light_count = {n}: sphere light(s) 0..{n} of {count} {verb}, {how}"
    )];
    if n < all {
        notes.push(format!(
            "the shadow output holds at most {MAX_SHADOW_PLANES} lights: sphere lights \
             {n}..{count} keep their shadows as rendered"
        ));
    }
    notes
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(lights: usize) -> SceneInfo {
        let mut info = SceneInfo::unknown();
        info.sphere_lights = (0..lights).map(|i| [i as f32, 3.0, 0.0, 0.2]).collect();
        info
    }

    #[test]
    fn auto_takes_the_first_lights_up_to_the_planes() {
        let (mut light, mut count) = (Auto::Auto, 0);
        let notes = specialise_lights(&mut light, &mut count, &scene(10), "filtered", "x");
        assert_eq!(chosen_lights(light, count), (0..8).collect::<Vec<u32>>());
        assert!(notes.iter().any(|n| n.contains("8..10")), "{notes:?}");
        let (mut light, mut count) = (Auto::Auto, 2);
        specialise_lights(&mut light, &mut count, &scene(3), "filtered", "x");
        assert_eq!(chosen_lights(light, count), vec![0, 1]);
        // Before specialisation auto is the first light; a set light is that light alone.
        assert_eq!(chosen_lights(Auto::Auto, 0), vec![0]);
        assert_eq!(chosen_lights(Auto::Set(2), 5), vec![2]);
        assert!(chosen_lights(Auto::Set(-1), 5).is_empty());
        // No sphere light: none.
        let (mut light, mut count) = (Auto::Auto, 0);
        specialise_lights(&mut light, &mut count, &scene(0), "filtered", "x");
        assert!(chosen_lights(light, count).is_empty());
    }

    #[test]
    fn counts_and_lights_out_of_range_are_refused() {
        assert!(check_lights(Auto::Auto, 8, "filtered").is_ok());
        let e = format!("{:#}", check_lights(Auto::Auto, 9, "filtered").unwrap_err());
        assert!(e.contains("light_count") && e.contains("at most 8"), "{e}");
        assert!(check_light(Auto::Set(-2)).is_err());
        let e = format!(
            "{:#}",
            lights_of("sheared", &[0, 3], &scene(2)).unwrap_err()
        );
        assert!(e.contains("sheared") && e.contains("sphere light 3"), "{e}");
        assert_eq!(light_planes(&[]), LightPlanes::one(0));
        assert_eq!(light_planes(&[1, 2]), LightPlanes::of(&[1, 2]));
    }
}
