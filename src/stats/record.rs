//! What a render records in its AOV and samples files, so that filtering the file offline
//! repeats exactly what filtering at the end of the render did: the scene information the
//! filters specialise to, the filter that ran, and every filter's requested settings.

use std::collections::BTreeMap;

use anyhow::{Context as _, Result, anyhow};

use crate::render::SceneInfo;

/// The version of the record's keys.
pub const RECORD_VERSION: &str = "2";

/// A render's record (a TOML table of text attributes: the attribute `noisefree.record` of an
/// AOV file's header, a samples file's record, a partial file's `[record]`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderRecord {
    /// None in files written by other programs or older versions.
    pub scene: Option<SceneInfo>,
    /// The filter the render ran, if any.
    pub filter: Option<String>,
    /// Per filter: the requested settings (defaults, scene file, command line).
    pub settings: BTreeMap<String, toml::Table>,
    /// Other attributes (samples per pixel, the scene file, the seed: for people).
    pub extra: BTreeMap<String, String>,
}

impl RenderRecord {
    /// As `key → text` attributes.
    pub fn to_attributes(&self) -> BTreeMap<String, String> {
        let mut a = self.extra.clone();
        a.insert("record".into(), RECORD_VERSION.into());
        if let Some(s) = &self.scene {
            a.insert("scene_info".into(), s.to_toml());
        }
        if let Some(f) = &self.filter {
            a.insert("filter".into(), f.clone());
        }
        for (name, table) in &self.settings {
            a.insert(
                format!("filter.{name}"),
                toml::to_string(table).expect("a settings table serialises"),
            );
        }
        a
    }

    /// From attributes written by [`RenderRecord::to_attributes`] (or by anything else: what
    /// is not recognised is kept in `extra`).
    pub fn from_attributes(a: &BTreeMap<String, String>) -> Result<RenderRecord> {
        let mut r = RenderRecord::default();
        for (k, v) in a {
            if k == "scene_info" {
                r.scene = Some(SceneInfo::from_toml(v)?);
            } else if k == "filter" {
                r.filter = Some(v.clone());
            } else if let Some(name) = k.strip_prefix("filter.") {
                let t: toml::Table = toml::from_str(v)
                    .map_err(|e| anyhow!("{}", e.message()))
                    .with_context(|| format!("the recorded settings of the {name} filter"))?;
                r.settings.insert(name.to_string(), t);
            } else if k != "record" {
                r.extra.insert(k.clone(), v.clone());
            }
        }
        Ok(r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_through_attributes() {
        let mut r = RenderRecord {
            scene: Some(SceneInfo::unknown()),
            filter: Some("ddf".into()),
            ..Default::default()
        };
        let mut t = toml::Table::new();
        t.insert("sigma".into(), toml::Value::Float(0.1f32 as f64));
        t.insert("sky".into(), toml::Value::String("auto".into()));
        r.settings.insert("ddf".into(), t);
        r.extra.insert("spp".into(), "8".into());
        let back = RenderRecord::from_attributes(&r.to_attributes()).unwrap();
        assert_eq!(back, r);
    }
}
