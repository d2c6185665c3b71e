//! The device's own ceilings, measured by the micro-kernels of kernels/bench/roofline.cl: the
//! arithmetic peak (fused multiply-adds on 8 independent chains per work-item, of float16s and
//! of floats), the cost of one `exp` in those flops, and STREAM's triad bandwidth. Each kernel's output has a plain
//! Rust reference here (`reference_*`), compared in tests/roofline.rs.

use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context as _, Result, bail};
use ocl::{Buffer, Kernel, Program};

use crate::gpu::{Gpu, enqueue, event_duration};
use crate::layout::Float4;

/// Independent chains per work-item (ROOFLINE_CHAINS in the kernels).
pub const CHAINS: usize = 8;
/// The chains' multiplier and addend: |b| < 1, so each chain tends to c / (1 - b) = 1.
pub const FMA_B: f32 = 0.999;
pub const FMA_C: f32 = 0.001;

/// What the micro-kernels measured: the best of several runs each.
#[derive(Clone, Copy, Debug)]
pub struct Peaks {
    /// Fused multiply-adds on float16 chains (explicit SIMD), 2 flops each, in GFLOP/s.
    pub gflops: f64,
    /// The same on float chains: the ceiling of code the compiler does not vectorise.
    pub gflops_scalar: f64,
    /// `exp` on float16 chains, in G/s.
    pub gexps: f64,
    /// `exp` on float chains, in G/s.
    pub gexps_scalar: f64,
    /// STREAM triad bandwidth in GB/s (32 bytes read + 16 written per float4).
    pub gbps: f64,
}

impl Peaks {
    /// One `exp` in flops: the FMA flops the device does in the time of one exp, both on
    /// float16s. The filters' weights are exponentials, so their arithmetic counts each exp at
    /// this price.
    pub fn exp_flops(&self) -> f64 {
        self.gflops / self.gexps
    }

    /// The arithmetic intensity (flops per byte) above which a kernel is bound by arithmetic
    /// rather than memory: the roofline's ridge.
    pub fn ridge(&self) -> f64 {
        self.gflops / self.gbps
    }

    /// The roofline: the most a kernel of `intensity` flops per byte can reach, in GFLOP/s.
    pub fn attainable(&self, intensity: f64) -> f64 {
        self.gflops.min(intensity * self.gbps)
    }
}

/// A micro-kernel's chain step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Op {
    /// a <- fma(a, FMA_B, FMA_C): 2 flops.
    Fma,
    /// a <- exp(-a).
    Exp,
}

fn program(gpu: &Gpu) -> Result<Program> {
    gpu.program("bench/roofline.cl", &[], "")
}

/// The initial value of chain `k` in lane `l` of work-item `i` (ROOFLINE_INITIAL).
fn initial(i: usize, k: usize, l: usize) -> f32 {
    ((i + k * 16 + l) & 15) as f32 * 0.0625
}

/// Runs the `op` micro-kernel on chains of `lanes` floats (1 or 16) on `work_items`
/// work-items for `iterations` steps: the per-work-item sums and the kernel time.
pub fn chains(
    gpu: &Arc<Gpu>,
    op: Op,
    lanes: usize,
    work_items: usize,
    iterations: u32,
) -> Result<(Vec<f32>, Duration)> {
    let name = match (op, lanes) {
        (Op::Fma, 16) => "peak_fma",
        (Op::Exp, 16) => "peak_exp",
        (Op::Fma, 1) => "peak_fma_scalar",
        (Op::Exp, 1) => "peak_exp_scalar",
        _ => bail!("the roofline micro-kernels have chains of 1 or 16 lanes, not {lanes}"),
    };
    let out = gpu.zeroed::<f32>(work_items, "roofline output")?;
    let p = program(gpu)?;
    let mut k = Kernel::builder();
    k.program(&p)
        .name(name)
        .queue(gpu.queue.clone())
        .global_work_size(work_items)
        .arg(&out)
        .arg(iterations as i32);
    if op == Op::Fma {
        k.arg(FMA_B).arg(FMA_C);
    }
    let kernel = k.build().context("creating a roofline micro-kernel")?;
    // SAFETY: `out` holds one float per work-item and lives until the event is waited on.
    let t = event_duration(&unsafe { enqueue(&kernel, "a roofline micro-kernel")? })?;
    let mut v = vec![0f32; work_items];
    out.read(&mut v)
        .enq()
        .context("reading the roofline output")?;
    Ok((v, t))
}

/// The plain Rust reference of the chain micro-kernels: the same operations in the same
/// order (`mul_add` is OpenCL's correctly rounded fma); the sum chain by chain, then lane by
/// lane.
pub fn reference_chains(op: Op, lanes: usize, work_items: usize, iterations: u32) -> Vec<f32> {
    (0..work_items)
        .map(|i| {
            let mut a: Vec<Vec<f32>> = (0..CHAINS)
                .map(|k| (0..lanes).map(|l| initial(i, k, l)).collect())
                .collect();
            for _ in 0..iterations {
                for x in a.iter_mut().flatten() {
                    *x = match op {
                        Op::Exp => (-*x).exp(),
                        Op::Fma => x.mul_add(FMA_B, FMA_C),
                    };
                }
            }
            let mut v = a[0].clone();
            for chain in &a[1..] {
                for (s, x) in v.iter_mut().zip(chain) {
                    *s += x;
                }
            }
            v.iter().fold(0.0, |s, x| s + x)
        })
        .collect()
}

/// STREAM's triad a = b + s c over `n` float4s, its buffers kept for repeated runs.
pub struct Triad {
    kernel: Kernel,
    a: Buffer<Float4>,
    _b: Buffer<Float4>,
    _c: Buffer<Float4>,
    pub n: usize,
}

/// The triad's inputs, element `i`: b = (i, i+1, i+2, i+3) / 1024 and c = 1 - b / 2.
pub fn triad_inputs(n: usize) -> (Vec<Float4>, Vec<Float4>) {
    let b: Vec<Float4> = (0..n)
        .map(|i| Float4(std::array::from_fn(|k| ((i + k) % 4096) as f32 / 1024.0)))
        .collect();
    let c = b
        .iter()
        .map(|v| Float4(v.0.map(|x| 1.0 - x / 2.0)))
        .collect();
    (b, c)
}

pub const TRIAD_S: f32 = 3.0;

impl Triad {
    pub fn new(gpu: &Arc<Gpu>, n: usize) -> Result<Triad> {
        let (b, c) = triad_inputs(n);
        let a = gpu.zeroed::<Float4>(n, "roofline triad")?;
        let b = gpu.upload(&b)?;
        let c = gpu.upload(&c)?;
        let p = program(gpu)?;
        let kernel = Kernel::builder()
            .program(&p)
            .name("stream_triad")
            .queue(gpu.queue.clone())
            .global_work_size(n)
            .arg(&a)
            .arg(&b)
            .arg(&c)
            .arg(TRIAD_S)
            .build()
            .context("creating the triad kernel")?;
        Ok(Triad {
            kernel,
            a,
            _b: b,
            _c: c,
            n,
        })
    }

    /// One run's kernel time.
    pub fn run(&self) -> Result<Duration> {
        // SAFETY: the three buffers hold `n` float4s and live as long as `self`.
        event_duration(&unsafe { enqueue(&self.kernel, "the triad kernel")? })
    }

    /// Bytes STREAM counts for one run.
    pub fn bytes(&self) -> f64 {
        48.0 * self.n as f64
    }

    pub fn result(&self) -> Result<Vec<Float4>> {
        let mut v = vec![Float4::default(); self.n];
        self.a
            .read(&mut v)
            .enq()
            .context("reading the triad output")?;
        Ok(v)
    }
}

/// The plain Rust reference of `stream_triad`.
pub fn reference_triad(n: usize) -> Vec<Float4> {
    let (b, c) = triad_inputs(n);
    b.iter()
        .zip(&c)
        .map(|(b, c)| Float4(std::array::from_fn(|k| b.0[k] + TRIAD_S * c.0[k])))
        .collect()
}

/// Best of `runs` runs of `run`, after one warm-up.
fn best(runs: usize, mut run: impl FnMut() -> Result<Duration>) -> Result<Duration> {
    run()?;
    let mut t = Duration::MAX;
    for _ in 0..runs {
        t = t.min(run()?);
    }
    Ok(t)
}

/// Measures the ceilings. Enough work-items to fill every compute unit several times (4096
/// per unit, 16 times as many for float chains: a GPU needs ~2048 resident threads per
/// multiprocessor to hide latency),
/// and iterations doubled until a run takes `min_ms`, so launch overhead does not count.
pub fn measure(gpu: &Arc<Gpu>, quick: bool) -> Result<Peaks> {
    let units = gpu.summary.compute_units.max(1) as usize;
    let work_items = units * if quick { 256 } else { 4096 };
    let min = Duration::from_millis(if quick { 2 } else { 50 });
    let runs = if quick { 2 } else { 5 };
    // Operations per second of each micro-kernel: every lane of every chain of every
    // work-item steps `iterations` times.
    let rate = |op: Op, lanes: usize| -> Result<f64> {
        let items = if lanes == 1 {
            work_items * 16
        } else {
            work_items
        };
        let mut iterations = 16u32;
        while chains(gpu, op, lanes, items, iterations)?.1 < min && iterations < 1 << 24 {
            iterations *= 2;
        }
        let t = best(runs, || Ok(chains(gpu, op, lanes, items, iterations)?.1))?;
        let ops = (items * CHAINS * lanes) as f64 * iterations as f64;
        Ok(ops / t.as_secs_f64() / 1e9)
    };
    let (fma, fma_scalar) = (rate(Op::Fma, 16)?, rate(Op::Fma, 1)?);
    let (exp, exp_scalar) = (rate(Op::Exp, 16)?, rate(Op::Exp, 1)?);
    // Buffers well beyond any cache: 3 x 256 MiB (3 x 4 MiB with --quick), within the
    // device's largest allocation.
    let max_elems = (gpu.summary.max_alloc_bytes / 16).max(1) as usize;
    let n = (if quick { 1 << 18 } else { 1 << 24 }).min(max_elems);
    let triad = Triad::new(gpu, n)?;
    let t = best(runs, || triad.run())?;
    Ok(Peaks {
        gflops: 2.0 * fma,
        gflops_scalar: 2.0 * fma_scalar,
        gexps: exp,
        gexps_scalar: exp_scalar,
        gbps: triad.bytes() / t.as_secs_f64() / 1e9,
    })
}
