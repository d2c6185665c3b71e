//! Filter options shared by `render` and `filter`, merged with a scene's `[filter]` table
//! (the command line wins), into one [`crate::filters::method::Method`].

use anyhow::{Result, bail};
use clap::{Args, ValueEnum};

use crate::filters::atrous::AtrousSettings;
use crate::filters::ddf::{DdfSettings, DirectionTerm, Variant};
use crate::filters::method::Method as FilterMethod;
use crate::filters::rpf::{RpfSettings, SceneKind};
use crate::scene::Setting;
use crate::scene::file::FilterSection;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Method {
    /// No filter: the path-traced image as it is.
    None,
    /// The data-driven filter of thesis ch. 6.
    Ddf,
    /// Random Parameter Filtering (thesis ch. 5; slow, on the host).
    Rpf,
    /// The edge-avoiding à-trous wavelet filter (Dammertz et al. 2010).
    Atrous,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum VariantArg {
    Naive,
    Vector,
    Rows,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum DirectionArg {
    /// eq. 6.14 as printed (its factor cancels).
    Thesis,
    /// exp(-sigma2 |d - d_N|^2) on mean first-bounce directions.
    Difference,
}

#[derive(Args, Debug, Clone, Default)]
pub struct FilterArgs {
    /// Filter to apply [default: the scene's [filter] method, else none].
    #[arg(long, value_enum)]
    pub filter: Option<Method>,
    /// Data-driven filter: kernel width kw, odd (Table 6.2) [default: 21].
    #[arg(long)]
    pub kw: Option<u32>,
    /// Data-driven filter: use only every second neighbour in x and y (§6.3.3).
    #[arg(long)]
    pub holes: bool,
    /// Data-driven filter: direct colour sigma_dc [default: 0.75].
    #[arg(long)]
    pub sigma_dc: Option<f32>,
    /// Data-driven filter: indirect colour sigma_ic [default: 0.5].
    #[arg(long)]
    pub sigma_ic: Option<f32>,
    /// Data-driven filter: sigma_f as depth,normal,texture,direction,texture2
    /// [default: 1.75,0.25,0.1,0.75,0.1].
    #[arg(long, value_delimiter = ',')]
    pub sigma_f: Option<Vec<f32>>,
    /// Data-driven filter: variance scales s_f as depth,normal,texture,direction,texture2.
    #[arg(long, value_delimiter = ',')]
    pub variance_scale: Option<Vec<f32>>,
    /// Data-driven filter: the direction factor of eq. 6.14.
    #[arg(long, value_enum)]
    pub direction: Option<DirectionArg>,
    /// Data-driven filter: drop the texture2 term of eq. 6.14.
    #[arg(long)]
    pub no_texture2: bool,
    /// Data-driven filter: kernel variant (§6.3) [default: rows].
    #[arg(long, value_enum)]
    pub variant: Option<VariantArg>,
    /// Data-driven filter: work-group size of the rows variant [default: 64].
    #[arg(long)]
    pub work_group: Option<u32>,
    /// RPF: sigma^2_8 of eq. 5.17 [default: 0.02 indoors, 0.002 outdoors].
    #[arg(long)]
    pub rpf_sigma8: Option<f32>,
    /// RPF: seed of the neighbourhood sampling [default: 0].
    #[arg(long)]
    pub rpf_seed: Option<u32>,
    /// À-trous: number of passes [default: 5].
    #[arg(long)]
    pub atrous_iterations: Option<u32>,
    /// À-trous: colour sigma of the first pass, halved every pass.
    #[arg(long)]
    pub atrous_sigma_color: Option<f32>,
    /// À-trous: normal sigma.
    #[arg(long)]
    pub atrous_sigma_normal: Option<f32>,
    /// À-trous: position sigma, in pixel footprints.
    #[arg(long)]
    pub atrous_sigma_position: Option<f32>,
    /// À-trous: filter the beauty as the paper does, not light divided by albedo.
    #[arg(long)]
    pub atrous_beauty: bool,
}

fn five(v: &Option<Vec<f32>>, flag: &str) -> Result<Option<[f32; 5]>> {
    match v {
        None => Ok(None),
        Some(v) if v.len() == 5 => Ok(Some([v[0], v[1], v[2], v[3], v[4]])),
        Some(v) => bail!(
            "--{flag} takes 5 comma-separated values (depth,normal,texture,direction,texture2), got {}",
            v.len()
        ),
    }
}

impl FilterArgs {
    /// The method to run: the flag, else the scene's `[filter] method`, else none.
    pub fn method(&self, section: Option<&FilterSection>) -> Result<Method> {
        if let Some(m) = self.filter {
            return Ok(m);
        }
        match section.and_then(|s| s.method.as_deref()) {
            None | Some("none") => Ok(Method::None),
            Some("ddf") => Ok(Method::Ddf),
            Some("rpf") => Ok(Method::Rpf),
            Some("atrous") => Ok(Method::Atrous),
            Some(other) => bail!(
                "[filter] method {other:?} is not a filter noisefree has (none, ddf, rpf, atrous)"
            ),
        }
    }

    /// The filter with its settings: defaults, then the scene's `[filter]`, then the flags.
    /// `setting` picks RPF's sigma^2_8 when nothing sets it.
    pub fn build(
        &self,
        method: Method,
        section: Option<&FilterSection>,
        setting: Setting,
    ) -> Result<Option<FilterMethod>> {
        Ok(match method {
            Method::None => None,
            Method::Ddf => {
                let (settings, variant) = self.ddf(section)?;
                Some(FilterMethod::Ddf { settings, variant })
            }
            Method::Rpf => Some(FilterMethod::Rpf(self.rpf(section, setting)?)),
            Method::Atrous => Some(FilterMethod::Atrous(self.atrous(section)?)),
        })
    }

    pub fn rpf(&self, section: Option<&FilterSection>, setting: Setting) -> Result<RpfSettings> {
        let kind = if setting == Setting::Outdoor {
            SceneKind::Outdoor
        } else {
            SceneKind::Indoor
        };
        let mut s = RpfSettings::for_scene(kind);
        if let Some(sec) = section {
            if let Some(v) = sec.rpf_sigma8 {
                s.sigma2_8 = v;
            }
            if let Some(v) = sec.rpf_seed {
                s.seed = v;
            }
        }
        if let Some(v) = self.rpf_sigma8 {
            s.sigma2_8 = v;
        }
        if let Some(v) = self.rpf_seed {
            s.seed = v;
        }
        s.validate()?;
        Ok(s)
    }

    pub fn atrous(&self, section: Option<&FilterSection>) -> Result<AtrousSettings> {
        let mut s =
            if self.atrous_beauty || section.and_then(|x| x.atrous_demodulate) == Some(false) {
                AtrousSettings::for_beauty()
            } else {
                AtrousSettings::default()
            };
        if let Some(sec) = section {
            s.iterations = sec.atrous_iterations.unwrap_or(s.iterations);
            s.sigma_color = sec.atrous_sigma_color.unwrap_or(s.sigma_color);
            s.sigma_normal = sec.atrous_sigma_normal.unwrap_or(s.sigma_normal);
            s.sigma_position = sec.atrous_sigma_position.unwrap_or(s.sigma_position);
        }
        s.iterations = self.atrous_iterations.unwrap_or(s.iterations);
        s.sigma_color = self.atrous_sigma_color.unwrap_or(s.sigma_color);
        s.sigma_normal = self.atrous_sigma_normal.unwrap_or(s.sigma_normal);
        s.sigma_position = self.atrous_sigma_position.unwrap_or(s.sigma_position);
        s.validate()?;
        Ok(s)
    }

    /// Data-driven filter settings: defaults (Table 7.2), then the scene's `[filter]`, then
    /// the flags.
    pub fn ddf(&self, section: Option<&FilterSection>) -> Result<(DdfSettings, Variant)> {
        let mut s = DdfSettings::default();
        let empty = FilterSection::default();
        let sec = section.unwrap_or(&empty);
        let direction = |d: &str| match d {
            "thesis" => Ok(DirectionTerm::Thesis),
            "difference" => Ok(DirectionTerm::Difference),
            other => {
                bail!("[filter] direction must be \"thesis\" or \"difference\", got {other:?}")
            }
        };
        s.kw = sec.kw.unwrap_or(s.kw);
        s.holes = sec.holes.unwrap_or(s.holes);
        s.sigma_dc = sec.sigma_dc.unwrap_or(s.sigma_dc);
        s.sigma_ic = sec.sigma_ic.unwrap_or(s.sigma_ic);
        s.sigma_f = sec.sigma_f.unwrap_or(s.sigma_f);
        s.variance_scale = sec.variance_scale.unwrap_or(s.variance_scale);
        if let Some(d) = &sec.direction {
            s.direction = direction(d)?;
        }
        s.texture2 = sec.texture2.unwrap_or(s.texture2);
        let mut variant = match sec.variant.as_deref() {
            None | Some("rows") => VariantArg::Rows,
            Some("naive") => VariantArg::Naive,
            Some("vector") => VariantArg::Vector,
            Some(other) => bail!("[filter] variant must be naive, vector or rows, got {other:?}"),
        };
        let mut work_group = sec.work_group.unwrap_or(64);

        s.kw = self.kw.unwrap_or(s.kw);
        s.holes |= self.holes;
        s.sigma_dc = self.sigma_dc.unwrap_or(s.sigma_dc);
        s.sigma_ic = self.sigma_ic.unwrap_or(s.sigma_ic);
        if let Some(v) = five(&self.sigma_f, "sigma-f")? {
            s.sigma_f = v;
        }
        if let Some(v) = five(&self.variance_scale, "variance-scale")? {
            s.variance_scale = v;
        }
        if let Some(d) = self.direction {
            s.direction = match d {
                DirectionArg::Thesis => DirectionTerm::Thesis,
                DirectionArg::Difference => DirectionTerm::Difference,
            };
        }
        if self.no_texture2 {
            s.texture2 = false;
        }
        variant = self.variant.unwrap_or(variant);
        work_group = self.work_group.unwrap_or(work_group);
        s.validate()?;
        let variant = match variant {
            VariantArg::Naive => Variant::Naive,
            VariantArg::Vector => Variant::Vector,
            VariantArg::Rows => Variant::Rows {
                work_group: work_group as usize,
            },
        };
        Ok((s, variant))
    }
}
