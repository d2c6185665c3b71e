//! Filter options shared by `render` and `filter`, merged with a scene's `[filter]` table
//! (the command line wins).

use anyhow::{Result, bail};
use clap::{Args, ValueEnum};

use crate::filters::ddf::{DdfSettings, DirectionTerm, Variant};
use crate::scene::file::FilterSection;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Method {
    /// No filter: the path-traced image as it is.
    None,
    /// The data-driven filter of thesis ch. 6.
    Ddf,
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
    /// Kernel width kw, odd (Table 6.2) [default: 21].
    #[arg(long)]
    pub kw: Option<u32>,
    /// Use only every second neighbour in x and y (§6.3.3).
    #[arg(long)]
    pub holes: bool,
    /// Direct colour sigma_dc [default: 0.75].
    #[arg(long)]
    pub sigma_dc: Option<f32>,
    /// Indirect colour sigma_ic [default: 0.5].
    #[arg(long)]
    pub sigma_ic: Option<f32>,
    /// sigma_f as depth,normal,texture,direction,texture2 [default: 1.75,0.25,0.1,0.75,0.1].
    #[arg(long, value_delimiter = ',')]
    pub sigma_f: Option<Vec<f32>>,
    /// Variance scales s_f as depth,normal,texture,direction,texture2.
    #[arg(long, value_delimiter = ',')]
    pub variance_scale: Option<Vec<f32>>,
    /// The direction factor of eq. 6.14.
    #[arg(long, value_enum)]
    pub direction: Option<DirectionArg>,
    /// Drop the texture2 term of eq. 6.14.
    #[arg(long)]
    pub no_texture2: bool,
    /// Filter kernel variant (§6.3) [default: rows].
    #[arg(long, value_enum)]
    pub variant: Option<VariantArg>,
    /// Work-group size of the rows variant [default: 64].
    #[arg(long)]
    pub work_group: Option<u32>,
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
            Some(other) => {
                bail!("[filter] method {other:?} is not a filter noisefree has (none, ddf)")
            }
        }
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
        if let Some(v) = sec.kw {
            s.kw = v;
        }
        if let Some(v) = sec.holes {
            s.holes = v;
        }
        if let Some(v) = sec.sigma_dc {
            s.sigma_dc = v;
        }
        if let Some(v) = sec.sigma_ic {
            s.sigma_ic = v;
        }
        if let Some(v) = sec.sigma_f {
            s.sigma_f = v;
        }
        if let Some(v) = sec.variance_scale {
            s.variance_scale = v;
        }
        if let Some(d) = &sec.direction {
            s.direction = direction(d)?;
        }
        if let Some(v) = sec.texture2 {
            s.texture2 = v;
        }
        let mut variant = match sec.variant.as_deref() {
            None | Some("rows") => VariantArg::Rows,
            Some("naive") => VariantArg::Naive,
            Some("vector") => VariantArg::Vector,
            Some(other) => bail!("[filter] variant must be naive, vector or rows, got {other:?}"),
        };
        let mut work_group = sec.work_group.unwrap_or(64);

        if let Some(v) = self.kw {
            s.kw = v;
        }
        s.holes |= self.holes;
        if let Some(v) = self.sigma_dc {
            s.sigma_dc = v;
        }
        if let Some(v) = self.sigma_ic {
            s.sigma_ic = v;
        }
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
        if let Some(v) = self.variant {
            variant = v;
        }
        if let Some(v) = self.work_group {
            work_group = v;
        }
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
