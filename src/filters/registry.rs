//! The registry of filters, and how a filter gets its settings.
//!
//! Settings come in layers, each overriding the one before key by key:
//! 1. the filter's defaults (its settings struct, [`super::settings`]);
//! 2. what an AOV or samples file recorded of the render it came from (offline filtering);
//! 3. the scene file's `[filter.<name>]` table;
//! 4. the command line (`--kw 15`, `--atrous-iterations 3`).
//!
//! The result (the *requested* settings, which may say `auto`) is what AOV files record; the
//! filter then specialises it to the scene ([`super::FilterKind::specialise`]). Offline
//! filtering repeats the same steps from the recorded settings and the recorded scene
//! information, so it gives the same bytes as filtering at the end of the render.

use std::collections::BTreeMap;
use std::sync::Arc;

use anyhow::{Context as _, Result, bail};
use clap::{Arg, ArgAction, ArgMatches};

use super::settings::{self, FieldDoc, display_value, overlay};
use super::{Filter, FilterKind, PreparedFilter, Purpose};
use crate::gpu::Gpu;
use crate::layout::outputs::OutputSet;
use crate::render::{FrameInfo, RenderOptions, SceneInfo};

type Prepare = dyn Fn(&FrameInfo, &Arc<Gpu>) -> Result<Box<dyn PreparedFilter>> + Send + Sync;
type AdjustRender = dyn Fn(&mut RenderOptions) + Send + Sync;

/// A filter with its settings, checked and specialised to one scene.
pub struct Configured {
    name: &'static str,
    fields: &'static [FieldDoc],
    requested: toml::Table,
    effective: toml::Table,
    notes: Vec<String>,
    needs: OutputSet,
    purpose: Purpose,
    applies: bool,
    prepare: Box<Prepare>,
    render: Box<AdjustRender>,
}

impl std::fmt::Debug for Configured {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Configured")
            .field("name", &self.name)
            .field("effective", &self.effective)
            .finish_non_exhaustive()
    }
}

impl Configured {
    pub(super) fn new<K: FilterKind>(
        requested: toml::Table,
        typed: K::Settings,
        notes: Vec<String>,
        scene: &SceneInfo,
    ) -> Configured {
        use super::DeclaredSettings as _;
        let effective = settings::to_table(&typed);
        let needs = K::needs(&typed);
        let applies = K::applies(&typed, scene);
        let for_render = typed.clone();
        Configured {
            name: K::NAME,
            fields: K::Settings::fields(),
            requested,
            effective,
            notes,
            needs,
            purpose: K::PURPOSE,
            applies,
            prepare: Box::new(move |frame, gpu| K::prepare(&typed, frame, gpu)),
            render: Box::new(move |options| K::render_options(&for_render, options)),
        }
    }

    /// A filter with typed settings (benchmarks, tests): checked and specialised to `scene`.
    pub fn typed<K: FilterKind>(settings: K::Settings, scene: &SceneInfo) -> Result<Configured> {
        K::check(&settings)?;
        let requested = settings::to_table(&settings);
        let mut typed = settings;
        let notes = K::specialise(&mut typed, scene);
        Ok(Configured::new::<K>(requested, typed, notes, scene))
    }

    pub fn name(&self) -> &'static str {
        self.name
    }

    /// The outputs the renderer must gather.
    pub fn needs(&self) -> OutputSet {
        self.needs
    }

    /// What the filter is for.
    pub fn purpose(&self) -> Purpose {
        self.purpose
    }

    /// Whether the filter changes anything on this scene ([`FilterKind::applies`]).
    pub fn applies(&self) -> bool {
        self.applies
    }

    /// Sets how the renderer gathers what the filter needs (after `outputs` is chosen).
    pub fn adjust_render(&self, options: &mut RenderOptions) {
        (self.render)(options)
    }

    /// The settings as asked for (may say `auto`): what AOV files record.
    pub fn requested(&self) -> &toml::Table {
        &self.requested
    }

    /// The settings after specialisation: what runs.
    pub fn effective(&self) -> &toml::Table {
        &self.effective
    }

    /// One line per decision the specialisation made.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// The notes a user must see whether or not they ask for `--explain`: those the filter
    /// wrote as "warning: ..." (it runs, but not as the scene would want).
    pub fn warnings(&self) -> impl Iterator<Item = &str> {
        self.notes
            .iter()
            .map(String::as_str)
            .filter(|n| n.starts_with("warning: "))
    }

    /// `key = value` lines of the effective settings, `auto` choices marked, then the notes.
    pub fn describe(&self) -> String {
        let mut s = String::new();
        for f in self.fields {
            let (Some(eff), req) = (self.effective.get(f.name), self.requested.get(f.name)) else {
                continue;
            };
            let auto = req.is_some_and(|r| r.as_str() == Some("auto"));
            s.push_str(&format!(
                "{} = {}{}\n",
                f.name,
                display_value(eff),
                if auto { "  (auto)" } else { "" }
            ));
        }
        for n in &self.notes {
            s.push_str(&format!("  {n}\n"));
        }
        s
    }

    /// Builds the filter for frames like `frame` on `gpu`.
    pub fn prepare(&self, frame: &FrameInfo, gpu: &Arc<Gpu>) -> Result<Box<dyn PreparedFilter>> {
        (self.prepare)(frame, gpu).with_context(|| format!("preparing the {} filter", self.name))
    }
}

/// Where a filter's settings come from, besides its defaults (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct FilterRequest {
    /// Per filter: the requested settings an AOV or samples file recorded.
    pub recorded: BTreeMap<String, toml::Table>,
    /// Per filter: the scene file's `[filter.<name>]` table.
    pub scene: BTreeMap<String, toml::Table>,
    /// Where the scene tables were written, for messages (e.g. "scenes/x.toml").
    pub scene_origin: String,
    /// Per filter: 1-based line of the `[filter.<name>]` header in the scene file.
    pub scene_lines: BTreeMap<String, usize>,
    /// Per filter: the settings given on the command line.
    pub flags: BTreeMap<String, toml::Table>,
}

/// The filters a command can run.
pub struct Registry {
    filters: Vec<&'static dyn Filter>,
}

impl Registry {
    /// The filters noisefree has ([`super::builtin`]).
    pub fn builtin() -> Registry {
        Registry::of(super::builtin())
    }

    /// A registry of these filters. Panics on a repeated name or flag (a programming error the
    /// tests catch).
    pub fn of(filters: Vec<&'static dyn Filter>) -> Registry {
        let r = Registry { filters };
        let mut names = std::collections::BTreeSet::new();
        let mut flags = std::collections::BTreeSet::new();
        for f in &r.filters {
            assert!(names.insert(f.name()), "two filters named {}", f.name());
            for field in f.fields() {
                let flag = field.flag(f.flag_prefix());
                assert!(flags.insert(flag.clone()), "two filters use --{flag}");
            }
        }
        r
    }

    /// This registry and one more filter (a plug-in, or a test's).
    pub fn with(self, filter: &'static dyn Filter) -> Registry {
        let mut filters = self.filters;
        filters.push(filter);
        Registry::of(filters)
    }

    pub fn filters(&self) -> &[&'static dyn Filter] {
        &self.filters
    }

    pub fn names(&self) -> Vec<&'static str> {
        self.filters.iter().map(|f| f.name()).collect()
    }

    pub fn get(&self, name: &str) -> Result<&'static dyn Filter> {
        self.filters
            .iter()
            .find(|f| f.name() == name)
            .copied()
            .with_context(|| {
                format!(
                    "no filter named {name:?}; noisefree has: none, {}",
                    self.names().join(", ")
                )
            })
    }

    /// The command-line flags of every filter's settings, grouped by filter in `--help`.
    pub fn clap_args(&self) -> Vec<Arg> {
        let mut args = Vec::new();
        for f in &self.filters {
            let defaults = f.defaults();
            for field in f.fields() {
                let default = defaults
                    .get(field.name)
                    .map(display_value)
                    .unwrap_or_default();
                let mut a = Arg::new(format!("{}.{}", f.name(), field.name))
                    .long(field.flag(f.flag_prefix()))
                    .help(format!("{} [default: {default}]", field.help()))
                    .help_heading(format!("Settings of the {} filter", f.name()))
                    .action(ArgAction::Set);
                if field.is_switch() {
                    a = a
                        .num_args(0..=1)
                        .require_equals(true)
                        .default_missing_value("true")
                        .value_name(if field.ty == "bool" {
                            "true|false"
                        } else {
                            "auto|true|false"
                        });
                } else {
                    a = a
                        .value_name(value_name(field.ty))
                        .allow_negative_numbers(true);
                }
                args.push(a);
            }
        }
        args
    }

    /// The settings given on the command line, per filter.
    pub fn flag_tables(&self, m: &ArgMatches) -> BTreeMap<String, toml::Table> {
        let mut out = BTreeMap::new();
        for f in &self.filters {
            let defaults = f.defaults();
            let mut t = toml::Table::new();
            for field in f.fields() {
                let id = format!("{}.{}", f.name(), field.name);
                if let Ok(Some(raw)) = m.try_get_one::<String>(&id) {
                    let default = defaults
                        .get(field.name)
                        .cloned()
                        .unwrap_or(toml::Value::String(String::new()));
                    t.insert(
                        field.name.to_string(),
                        settings::parse_flag_value(raw, &default),
                    );
                }
            }
            if !t.is_empty() {
                out.insert(f.name().to_string(), t);
            }
        }
        out
    }

    /// Refuses tables for filters that do not exist (a typo in `[filter.<name>]`).
    pub fn check_request(&self, req: &FilterRequest) -> Result<()> {
        for name in req.scene.keys() {
            if self.get(name).is_err() {
                let at = req
                    .scene_lines
                    .get(name)
                    .map(|l| format!(":{l}"))
                    .unwrap_or_default();
                bail!(
                    "{}{at}: [filter.{name}]: no filter of that name (noisefree has: {})",
                    req.scene_origin,
                    self.names().join(", ")
                );
            }
        }
        Ok(())
    }

    /// One filter configured from `req` for `scene`. Errors name the layer they come from:
    /// the scene file (with its line) or the command line.
    pub fn configure(
        &self,
        filter: &'static dyn Filter,
        req: &FilterRequest,
        scene: &SceneInfo,
    ) -> Result<Configured> {
        let name = filter.name();
        let mut requested = filter.defaults();
        if let Some(t) = req.recorded.get(name) {
            overlay(&mut requested, t);
        }
        if let Some(t) = req.scene.get(name) {
            overlay(&mut requested, t);
            if let Err(e) = filter.configure(requested.clone(), scene) {
                let at = req
                    .scene_lines
                    .get(name)
                    .map(|l| format!(":{l}"))
                    .unwrap_or_default();
                return Err(e.context(format!("{}{at}: [filter.{name}]", req.scene_origin)));
            }
        }
        if let Some(t) = req.flags.get(name) {
            overlay(&mut requested, t);
            let flags: Vec<String> = t
                .keys()
                .filter_map(|k| filter.fields().iter().find(|f| f.name == k))
                .map(|f| format!("--{}", f.flag(filter.flag_prefix())))
                .collect();
            return filter
                .configure(requested, scene)
                .with_context(|| flags.join(" "));
        }
        let result = filter.configure(requested, scene);
        if req.recorded.contains_key(name) {
            result
                .with_context(|| format!("the settings of the {name} filter recorded in the file"))
        } else {
            result
        }
    }

    /// Every filter configured from `req` (so that an AOV file records settings for each).
    pub fn configure_all(&self, req: &FilterRequest, scene: &SceneInfo) -> Result<Vec<Configured>> {
        self.check_request(req)?;
        self.filters
            .iter()
            .map(|f| self.configure(*f, req, scene))
            .collect()
    }
}

fn value_name(ty: &str) -> &'static str {
    match ty {
        "u32" | "usize" | "i32" => "N",
        "f32" | "f64" => "X",
        "[f32; 5]" => "A,B,C,D,E",
        "[f32; 3]" => "C0,C1,C2",
        "Vec<u32>" => "N,N,...",
        "Auto<f32>" => "auto|X",
        "Auto<i32>" | "Auto<u32>" => "auto|N",
        _ => "VALUE",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_names_and_flags_are_unique_and_every_setting_has_docs() {
        let r = Registry::builtin();
        for f in r.filters() {
            assert!(!f.summary().is_empty());
            for field in f.fields() {
                assert!(
                    !field.help().is_empty(),
                    "{}.{} has no doc",
                    f.name(),
                    field.name
                );
                assert!(f.defaults().contains_key(field.name), "{}", field.name);
            }
        }
        assert!(r.get("nonexistent").is_err());
        // Every filter configures from its defaults for a scene nothing is known about.
        for f in r.filters() {
            r.configure(*f, &FilterRequest::default(), &SceneInfo::unknown())
                .unwrap_or_else(|e| panic!("{}: {e:#}", f.name()));
        }
    }

    #[test]
    fn layers_override_in_order_and_errors_name_their_layer() {
        let r = Registry::builtin();
        let ddf = r.get("ddf").unwrap();
        let table = |k: &str, v: i64| {
            let mut t = toml::Table::new();
            t.insert(k.into(), toml::Value::Integer(v));
            t
        };
        let mut req = FilterRequest {
            scene_origin: "scene.toml".into(),
            ..Default::default()
        };
        req.recorded.insert("ddf".into(), table("kw", 11));
        let c = r.configure(ddf, &req, &SceneInfo::unknown()).unwrap();
        assert_eq!(c.effective()["kw"].as_integer(), Some(11));
        req.scene.insert("ddf".into(), table("kw", 15));
        req.scene_lines.insert("ddf".into(), 7);
        let c = r.configure(ddf, &req, &SceneInfo::unknown()).unwrap();
        assert_eq!(c.effective()["kw"].as_integer(), Some(15));
        req.flags.insert("ddf".into(), table("kw", 9));
        let c = r.configure(ddf, &req, &SceneInfo::unknown()).unwrap();
        assert_eq!(c.effective()["kw"].as_integer(), Some(9));
        req.flags.insert("ddf".into(), table("kw", 8));
        let e = format!(
            "{:#}",
            r.configure(ddf, &req, &SceneInfo::unknown()).unwrap_err()
        );
        assert!(e.contains("--kw") && e.contains("odd"), "{e}");
        req.flags.clear();
        req.scene.insert("ddf".into(), table("kw", 8));
        let e = format!(
            "{:#}",
            r.configure(ddf, &req, &SceneInfo::unknown()).unwrap_err()
        );
        assert!(e.contains("scene.toml:7") && e.contains("odd"), "{e}");
        req.scene.clear();
        req.scene.insert("dff".into(), table("kw", 9));
        let e = r.check_request(&req).unwrap_err().to_string();
        assert!(e.contains("[filter.dff]") && e.contains("ddf"), "{e}");
    }

    /// scenes/README.md documents every filter's settings in a table; its defaults must be the
    /// ones the settings structs declare (the one place defaults are written).
    #[test]
    fn scene_file_reference_states_the_declared_defaults() {
        let doc = include_str!("../../scenes/README.md");
        let r = Registry::builtin();
        let section = &doc[doc.find("### `[filter]`").expect("the [filter] section")..];
        let mut table = None;
        let mut checked = 0;
        let same = |a: &toml::Value, b: &toml::Value| -> bool {
            match (a, b) {
                (toml::Value::Array(x), toml::Value::Array(y)) => {
                    x.len() == y.len()
                        && x.iter().zip(y).all(|(p, q)| {
                            display_value(p) == display_value(q)
                                || p.as_float().or(p.as_integer().map(|i| i as f64))
                                    == q.as_float().or(q.as_integer().map(|i| i as f64))
                        })
                }
                _ => a
                    .as_float()
                    .or(a.as_integer().map(|i| i as f64))
                    .zip(b.as_float().or(b.as_integer().map(|i| i as f64)))
                    .map_or(a == b, |(p, q)| p == q),
            }
        };
        for line in section.lines().take_while(|l| !l.starts_with("## ")) {
            let cells: Vec<&str> = line.split('|').map(str::trim).collect();
            if cells.len() < 5
                || cells[2].is_empty()
                || cells[2] == "setting"
                || cells[2].starts_with("---")
            {
                continue;
            }
            if let Some(t) = cells[1]
                .strip_prefix("`[filter.")
                .and_then(|t| t.strip_suffix("]`"))
            {
                table = Some(t.to_string());
            }
            let filter = r.get(table.as_deref().expect("a table first")).unwrap();
            let defaults = filter.defaults();
            let keys: Vec<&str> = cells[2]
                .split(',')
                .map(|k| k.trim().trim_matches('`'))
                .collect();
            let lit = cells[3].trim_matches('`');
            let values: Vec<String> =
                if keys.len() > 1 && !lit.starts_with('[') && lit.contains(',') {
                    lit.split(',').map(|v| v.trim().to_string()).collect()
                } else {
                    vec![lit.to_string(); keys.len()]
                };
            for (k, v) in keys.iter().zip(values) {
                let Ok(t) = toml::from_str::<toml::Table>(&format!("v = {v}")) else {
                    continue; // a pointer to the code ("see src/...")
                };
                let want = &defaults[*k];
                assert!(
                    same(&t["v"], want),
                    "scenes/README.md: [filter.{}] {k} = {v}, the code says {}",
                    filter.name(),
                    display_value(want)
                );
                checked += 1;
            }
        }
        assert!(checked >= 15, "only {checked} defaults checked");
    }
}
