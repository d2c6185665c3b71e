//! Several lights (DeCoro 2009 eq. 3.1: L = Σ_l ρ S_l L_l, each light with its own S_l): which
//! sphere lights the filter stylizes and with which controls. The filter's four quadratics are
//! every light's default; a table per light overrides any of them, or leaves that light's
//! shadow as rendered:
//!
//! ```toml
//! [filter.stylized-shadows]
//! inflation = [0.1, 0, 0]          # every light
//! [filter.stylized-shadows.lights.1]
//! softness = [0.4, 0, 0]           # sphere light 1 also gets a soft edge
//! [filter.stylized-shadows.lights.2]
//! stylize = false                  # sphere light 2's shadow stays as the path tracer made it
//! ```

use std::collections::BTreeMap;

use anyhow::{Result, bail};
use serde::{Deserialize, Serialize};

use super::transfer::Controls;

/// One light's overrides (`[filter.stylized-shadows.lights.<n>]`, n its number among the
/// scene's sphere lights); a control left out takes the filter's.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightControls {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inflation: Option<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub softness: Option<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub brightness: Option<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub abstraction: Option<[f32; 3]>,
    /// false: the light's shadow is not stylized (default true).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stylize: Option<bool>,
}

/// The per-light tables, keyed by the light's number as text (TOML keys are text).
pub type LightTable = BTreeMap<String, LightControls>;

impl LightControls {
    /// `base` with this light's overrides.
    pub fn over(&self, base: &Controls) -> Controls {
        Controls {
            inflation: self.inflation.unwrap_or(base.inflation),
            softness: self.softness.unwrap_or(base.softness),
            brightness: self.brightness.unwrap_or(base.brightness),
            abstraction: self.abstraction.unwrap_or(base.abstraction),
        }
    }
}

/// The light numbers of the table, checked: whole numbers below 32 (the shadow output's light
/// set is a 32-bit mask).
pub fn check(table: &LightTable) -> Result<()> {
    for key in table.keys() {
        match key.parse::<u32>() {
            Ok(l) if l < 32 => {}
            _ => bail!(
                "lights.{key}: a per-light table is named by the sphere light's number \
                 (0, 1, ..., 31), as in [filter.stylized-shadows.lights.1]"
            ),
        }
    }
    Ok(())
}

/// Light `l`'s entry, if any.
pub fn entry(table: &LightTable, l: u32) -> Option<&LightControls> {
    table
        .iter()
        .find(|(k, _)| k.parse::<u32>() == Ok(l))
        .map(|(_, v)| v)
}

/// Light `l`'s controls: `base` with its overrides.
pub fn controls_of(table: &LightTable, base: &Controls, l: u32) -> Controls {
    entry(table, l).map_or(*base, |e| e.over(base))
}

/// Whether light `l` is stylized (its table does not say `stylize = false`).
pub fn stylized(table: &LightTable, l: u32) -> bool {
    entry(table, l).is_none_or(|e| e.stylize != Some(false))
}
