//! Mutual information from histograms (thesis §5.1.3, eq. 5.3, Algorithm 7).
//!
//! μ(X; Y) = H(X) + H(Y) − H(X, Y) in bits (Alg. 7: entropies with log₂), with the
//! probabilities estimated by counting the samples of the neighbourhood N in buckets.
//!
//! **Buckets (a reading; Alg. 7 leaves `CalculateBucket` undefined).** Each variable is
//! quantised on its own into `B` equal-width buckets spanning its range over N:
//! `bucket = ⌊B · (v − min) / (max − min)⌋`, the maximum going to the last bucket. A variable
//! whose values over N are all equal (zero range, e.g. the time parameter t, which is always 0)
//! fills one bucket: its entropy and every mutual information with it are exactly 0. Because
//! the bucketing only depends on the order and relative spacing of the values, it gives the
//! same buckets for the normalised samples of Alg. 6 lines 15-18 as for the raw ones, so
//! scaling the scene changes nothing here. `B` is [`super::RpfSettings::mi_buckets`], default
//! 5, the value the NVIDIA reference implementation of RPF settled on ("5 should be pretty close
//! to Sen's implementation, based on the cited Matlab code" of Peng et al.).
//!
//! The other reading, Peng's unit-wide buckets on the standardised values
//! ([`super::RpfSettings::mi_bucketing`] = "unit"), is in [`super::mi_unit`].
//!
//! The histogram estimate can come out a rounding error below zero for independent variables;
//! it is clamped to 0 (mutual information is never negative).

use super::bitsets::JointInput;
use super::mi_unit;
use super::cpu::Level;

/// Most buckets per variable ([`super::RpfSettings::mi_buckets`] is checked against it).
pub const MAX_BUCKETS: usize = 16;

/// Bucket of every value of `values` (module docs), written to `codes`; returns the number of
/// populated buckets.
pub fn quantize(values: &[f32], buckets: usize, codes: &mut [u8]) -> usize {
    assert!((1..=MAX_BUCKETS).contains(&buckets));
    assert_eq!(values.len(), codes.len());
    let (lo, hi) = min_max(values);
    let top = (buckets - 1) as f32;
    let range = hi - lo;
    let wide = hi as f64 - lo as f64;
    if wide.is_nan() || wide <= 0.0 || wide.is_infinite() {
        codes.fill(0);
        return usize::from(!values.is_empty());
    }
    if range.is_finite() {
        // Single precision is enough for a bucket index and lets the loop vectorise.
        let scale = buckets as f32 / range;
        for (c, &v) in codes.iter_mut().zip(values) {
            *c = ((v - lo) * scale).min(top) as u8;
        }
    } else {
        let scale = buckets as f64 / (hi as f64 - lo as f64);
        for (c, &v) in codes.iter_mut().zip(values) {
            *c = ((v as f64 - lo as f64) * scale).min(top as f64) as u8;
        }
    }
    let mut counts = [0u32; MAX_BUCKETS];
    for &c in codes.iter() {
        counts[c as usize] += 1;
    }
    counts.iter().filter(|&&c| c > 0).count()
}

/// Smallest and largest value (four independent lanes, so the loop is not one long chain).
fn min_max(values: &[f32]) -> (f32, f32) {
    let mut lo = [f32::INFINITY; 4];
    let mut hi = [f32::NEG_INFINITY; 4];
    let mut chunks = values.chunks_exact(4);
    for c in &mut chunks {
        for k in 0..4 {
            lo[k] = lo[k].min(c[k]);
            hi[k] = hi[k].max(c[k]);
        }
    }
    for &v in chunks.remainder() {
        lo[0] = lo[0].min(v);
        hi[0] = hi[0].max(v);
    }
    (
        lo[0].min(lo[1]).min(lo[2].min(lo[3])),
        hi[0].max(hi[1]).max(hi[2].max(hi[3])),
    )
}

/// Entropy in bits of a histogram of `total` samples.
pub fn entropy_of_counts(counts: &[u32], total: u64) -> f64 {
    if total == 0 {
        return 0.0;
    }
    let n = total as f64;
    let h: f64 = counts
        .iter()
        .filter(|&&c| c > 0)
        .map(|&c| {
            let p = c as f64 / n;
            -p * p.log2()
        })
        .sum();
    h.max(0.0)
}

/// Entropy in bits of `values` quantised into `buckets` buckets.
pub fn entropy(values: &[f32], buckets: usize) -> f64 {
    let mut codes = vec![0u8; values.len()];
    quantize(values, buckets, &mut codes);
    let mut counts = [0u32; MAX_BUCKETS];
    for &c in &codes {
        counts[c as usize] += 1;
    }
    entropy_of_counts(&counts[..buckets], values.len() as u64)
}

/// μ(X; Y) of eq. 5.3 in bits, Algorithm 7 with the buckets of the module docs. `x` and `y`
/// are the same samples' values of two variables.
pub fn mutual_information(x: &[f32], y: &[f32], buckets: usize) -> f64 {
    assert_eq!(
        x.len(),
        y.len(),
        "mutual information of unequal sample counts"
    );
    let n = x.len();
    let mut cx = vec![0u8; n];
    let mut cy = vec![0u8; n];
    quantize(x, buckets, &mut cx);
    quantize(y, buckets, &mut cy);
    let mut hx = [0u32; MAX_BUCKETS];
    let mut hy = [0u32; MAX_BUCKETS];
    let mut hxy = vec![0u32; buckets * buckets];
    for (&a, &b) in cx.iter().zip(&cy) {
        hx[a as usize] += 1;
        hy[b as usize] += 1;
        hxy[a as usize * buckets + b as usize] += 1;
    }
    let t = n as u64;
    let mi = entropy_of_counts(&hx[..buckets], t) + entropy_of_counts(&hy[..buckets], t)
        - entropy_of_counts(&hxy, t);
    mi.max(0.0)
}

/// The same estimate for many pairs of one neighbourhood, without allocating. Every variable is
/// quantised once into one bitset per bucket (bit j set when sample j falls in the bucket), and
/// its marginal entropy computed once. A joint count is then the population count of the AND of
/// two bitsets: `(B_x − 1)(B_y − 1)` sweeps of n/64 words for a pair whose variables fill B_x and
/// B_y buckets (the last row and column follow from the marginal counts), instead of one
/// histogram increment per sample. The counts are exact integers, so the estimate is the same
/// whatever the instruction set ([`super::cpu`]). Entropies use a table of c·log₂ c:
/// H = log₂ n − (1/n) Σ c log₂ c, summed in bucket order. Gives the same values as
/// [`mutual_information`] up to rounding (the unit tests compare them).
#[derive(Clone, Debug)]
pub struct MiWorkspace {
    buckets: usize,
    vars: usize,
    n: usize,
    /// 64-bit words per bitset: ⌈n / 64⌉ rounded up to a multiple of 8 (one AVX-512
    /// register; the words past n are 0).
    words: usize,
    /// Bucket codes of the variable being loaded.
    codes: Vec<u8>,
    /// Bitsets, variable-major, then bucket: `masks[(v · B + b) · words ..][..words]`.
    masks: Vec<u64>,
    /// Samples per bucket, `counts[v · B + b]`.
    counts: Vec<u32>,
    /// Entropy of each variable.
    entropy: Vec<f64>,
    /// Whether a variable fills more than one bucket (otherwise every μ with it is 0).
    varies: Vec<bool>,
    /// c · log₂ c for c = 0, 1, ...
    xlogx: Vec<f64>,
    /// Joint counts of the last pair, `B × B`.
    joint: Vec<u32>,
    /// Joint counts of a group of pairs ([`Self::mi_batch`]).
    joints: Vec<u32>,
    level: Level,
    /// Peng's unit buckets ([`super::mi_unit`]) instead of `B` over the range.
    unit: bool,
    /// Unit buckets: the states of each variable, variable-major (`n` each), their number,
    /// and scratch.
    states: Vec<u16>,
    count: Vec<usize>,
    table: Vec<u32>,
}

impl MiWorkspace {
    /// A workspace for `buckets` buckets per variable, on the best instruction set of this CPU.
    pub fn new(buckets: usize) -> MiWorkspace {
        Self::with_level(buckets, Level::detect())
    }

    /// A workspace that uses instruction-set level `level` (one of [`Level::available`]).
    pub fn with_level(buckets: usize, level: Level) -> MiWorkspace {
        assert!((2..=MAX_BUCKETS).contains(&buckets));
        MiWorkspace {
            buckets,
            vars: 0,
            n: 0,
            words: 0,
            codes: Vec::new(),
            masks: Vec::new(),
            counts: Vec::new(),
            entropy: Vec::new(),
            varies: Vec::new(),
            xlogx: vec![0.0],
            joint: vec![0; buckets * buckets],
            joints: Vec::new(),
            level,
            unit: false,
            states: Vec::new(),
            count: Vec::new(),
            table: Vec::new(),
        }
    }

    /// A workspace with Peng's unit buckets ([`super::mi_unit`]).
    pub fn unit(level: Level) -> MiWorkspace {
        MiWorkspace {
            unit: true,
            ..Self::with_level(MAX_BUCKETS, level)
        }
    }

    /// Quantises `rows.len()` variables of `n` samples each: variable v is
    /// `values[rows[v] * stride..][..n]`.
    pub fn load(&mut self, values: &[f32], rows: &[usize], stride: usize, n: usize) {
        let vars = rows.len();
        assert!(n <= stride && rows.iter().all(|&r| values.len() >= (r + 1) * stride));
        let b = self.buckets;
        let words = n.div_ceil(64).next_multiple_of(8);
        self.vars = vars;
        self.n = n;
        self.words = words;
        self.codes.resize(n, 0);
        self.masks.resize(vars * b * words, 0);
        self.counts.resize(vars * b, 0);
        self.entropy.resize(vars, 0.0);
        self.varies.resize(vars, false);
        while self.xlogx.len() <= n {
            let c = self.xlogx.len() as f64;
            self.xlogx.push(c * c.log2());
        }
        if self.unit {
            self.states.resize(vars * n, 0);
            self.count.resize(vars, 0);
        }
        for v in 0..vars {
            let values = &values[rows[v] * stride..rows[v] * stride + n];
            let masks = &mut self.masks[v * b * words..(v + 1) * b * words];
            let counts = &mut self.counts[v * b..(v + 1) * b];
            if self.unit {
                let states = &mut self.states[v * n..(v + 1) * n];
                let p = mi_unit::quantize_unit(values, states, &mut self.table);
                self.count[v] = p;
                let mut all = vec![0u32; p];
                for &c in states.iter() {
                    all[c as usize] += 1;
                }
                if p <= b {
                    for (c, &s) in self.codes.iter_mut().zip(states.iter()) {
                        *c = s as u8;
                    }
                    self.level.bitsets(&self.codes, b, words, masks);
                    counts.fill(0);
                    counts[..p].copy_from_slice(&all);
                }
                self.varies[v] = p > 1;
                self.entropy[v] = if p > 1 {
                    entropy_from(&self.xlogx, &all, n)
                } else {
                    0.0
                };
                continue;
            }
            let populated = match self.level.quantize_bitsets(values, b, words, masks, counts) {
                Some(populated) => populated,
                None => {
                    let populated = quantize(values, b, &mut self.codes);
                    self.level.bitsets(&self.codes, b, words, masks);
                    counts.fill(0);
                    for &c in &self.codes {
                        counts[c as usize] += 1;
                    }
                    populated
                }
            };
            self.varies[v] = populated > 1;
            self.entropy[v] = if populated > 1 {
                entropy_from(&self.xlogx, counts, n)
            } else {
                0.0
            };
        }
    }

    /// Entropy in bits of variable `v`.
    pub fn entropy(&self, v: usize) -> f64 {
        self.entropy[v]
    }

    /// μ(variable x; variable y) in bits.
    pub fn mi(&mut self, x: usize, y: usize) -> f64 {
        if !self.varies[x] || !self.varies[y] {
            return 0.0;
        }
        if self.unit && (self.count[x] > self.buckets || self.count[y] > self.buckets) {
            // A wide variable: its joint histogram counted directly, summed row-major.
            let n = self.n;
            let (px, py) = (self.count[x], self.count[y]);
            let (sx, sy) = (
                &self.states[x * n..(x + 1) * n],
                &self.states[y * n..(y + 1) * n],
            );
            let mut joint = std::mem::take(&mut self.table);
            mi_unit::joint_counts(sx, sy, px, py, &mut joint);
            let s: f64 = joint.iter().map(|&c| self.xlogx[c as usize]).sum();
            self.table = joint;
            let nf = n as f64;
            let h = (nf.log2() - s / nf).max(0.0);
            return (self.entropy[x] + self.entropy[y] - h).max(0.0);
        }
        let mut joint = std::mem::take(&mut self.joint);
        self.joint_counts(x, y, &mut joint);
        // Σ c log₂ c over the joint histogram, in bucket order (zeros add exactly 0).
        let s: f64 = joint.iter().map(|&c| self.xlogx[c as usize]).sum();
        self.joint = joint;
        self.mi_from(x, y, s)
    }

    /// The joint counts of variables x and y (bitsets), `B × B`.
    fn joint_counts(&self, x: usize, y: usize, out: &mut [u32]) {
        let (b, words) = (self.buckets, self.words);
        let set = |v: usize| &self.masks[v * b * words..(v + 1) * b * words];
        let count = |v: usize| &self.counts[v * b..(v + 1) * b];
        self.level.joint_counts(
            JointInput {
                mx: set(x),
                my: set(y),
                cx: count(x),
                cy: count(y),
                buckets: b,
                words,
            },
            out,
        );
    }

    /// μ(x; y) from Σ c log₂ c over their joint histogram.
    fn mi_from(&self, x: usize, y: usize, s: f64) -> f64 {
        let nf = self.n as f64;
        let joint = (nf.log2() - s / nf).max(0.0);
        (self.entropy[x] + self.entropy[y] - joint).max(0.0)
    }

    /// [`Self::mi`] of every pair in `pairs` into `out`, the same values: four pairs' joint
    /// counts at a time, then their four Σ c log₂ c side by side, each in bucket order (one
    /// pair's sum is a chain of B² dependent additions; four chains overlap).
    pub fn mi_batch(&mut self, pairs: &[(usize, usize)], out: &mut [f64]) {
        assert_eq!(pairs.len(), out.len());
        const GROUP: usize = 4;
        let cells = self.buckets * self.buckets;
        let mut joints = std::mem::take(&mut self.joints);
        joints.resize(GROUP * cells, 0);
        for (group, results) in pairs.chunks(GROUP).zip(out.chunks_mut(GROUP)) {
            // The pairs that take the bitset path; the others are done one by one.
            let mut batched = [false; GROUP];
            for (g, (&(x, y), r)) in group.iter().zip(results.iter_mut()).enumerate() {
                if !self.varies[x] || !self.varies[y] {
                    *r = 0.0;
                } else if self.unit && (self.count[x] > self.buckets || self.count[y] > self.buckets)
                {
                    *r = self.mi(x, y);
                } else {
                    self.joint_counts(x, y, &mut joints[g * cells..(g + 1) * cells]);
                    batched[g] = true;
                }
            }
            let mut sums = [0.0f64; GROUP];
            for cell in 0..cells {
                for (g, sum) in sums.iter_mut().enumerate() {
                    *sum += self.xlogx[joints[g * cells + cell] as usize];
                }
            }
            for (g, (&(x, y), r)) in group.iter().zip(results.iter_mut()).enumerate() {
                if batched[g] {
                    *r = self.mi_from(x, y, sums[g]);
                }
            }
        }
        self.joints = joints;
    }
}

/// H = log₂ n − (1/n) Σ c log₂ c in bits, from bucket counts of n samples.
fn entropy_from(xlogx: &[f64], counts: &[u32], n: usize) -> f64 {
    if n == 0 {
        return 0.0;
    }
    let s: f64 = counts.iter().map(|&c| xlogx[c as usize]).sum();
    let n = n as f64;
    (n.log2() - s / n).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(state: &mut u64) -> f32 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*state >> 40) as f32 / (1u64 << 24) as f32
    }

    #[test]
    fn workspace_matches_the_plain_estimate() {
        let mut st = 7u64;
        let n = 1001;
        let mut values = vec![0.0f32; 3 * 1024];
        for j in 0..n {
            let a = lcg(&mut st);
            values[j] = a;
            values[1024 + j] = a * a + 0.1 * lcg(&mut st);
            values[2048 + j] = 3.0; // constant
        }
        let mut ws = MiWorkspace::new(5);
        ws.load(&values, &[0, 1, 2], 1024, n);
        let x = &values[..n];
        let y = &values[1024..1024 + n];
        let z = &values[2048..2048 + n];
        assert!((ws.mi(0, 1) - mutual_information(x, y, 5)).abs() < 1e-9);
        assert!((ws.mi(1, 0) - mutual_information(y, x, 5)).abs() < 1e-9);
        assert!((ws.entropy(0) - entropy(x, 5)).abs() < 1e-9);
        assert_eq!(ws.mi(0, 2), 0.0);
        assert_eq!(mutual_information(x, z, 5), 0.0);
        assert!((ws.mi(0, 0) - ws.entropy(0)).abs() < 1e-9);
    }

    /// Every instruction-set path gives the same bits, for sample counts on and off a multiple
    /// of 64, every bucket count, and variables that fill one, some or all buckets.
    #[test]
    fn every_instruction_set_gives_the_same_bits() {
        let levels = Level::available();
        let mut st = 11u64;
        for n in [1, 63, 64, 65, 700, 1283] {
            let vars = 5;
            let mut values = vec![0.0f32; vars * n];
            for j in 0..n {
                let a = lcg(&mut st);
                values[j] = a;
                values[n + j] = a * a + 0.2 * lcg(&mut st);
                values[2 * n + j] = lcg(&mut st);
                values[3 * n + j] = if a < 0.3 { 1.0 } else { 2.0 };
                values[4 * n + j] = -1.0;
            }
            for buckets in [2, 5, 8, 16] {
                let all: Vec<Vec<u64>> = levels
                    .iter()
                    .map(|&level| {
                        let mut ws = MiWorkspace::with_level(buckets, level);
                        ws.load(&values, &[0, 1, 2, 3, 4], n, n);
                        let mut bits = Vec::new();
                        for x in 0..vars {
                            bits.push(ws.entropy(x).to_bits());
                            for y in 0..vars {
                                bits.push(ws.mi(x, y).to_bits());
                            }
                        }
                        bits
                    })
                    .collect();
                for (level, bits) in levels.iter().zip(&all) {
                    assert_eq!(bits, &all[0], "{level:?}, n {n}, {buckets} buckets");
                }
                let mut ws = MiWorkspace::new(buckets);
                ws.load(&values, &[0, 1, 2, 3, 4], n, n);
                let plain = mutual_information(&values[..n], &values[n..2 * n], buckets);
                assert!((ws.mi(0, 1) - plain).abs() < 1e-9, "n {n}, {buckets} buckets");
            }
        }
    }

    #[test]
    fn quantize_spans_the_range() {
        let v = [0.0, 0.19, 0.2, 0.5, 0.99, 1.0];
        let mut c = [9u8; 6];
        assert_eq!(quantize(&v, 5, &mut c), 4);
        assert_eq!(c, [0, 0, 1, 2, 4, 4]);
        let mut c = [9u8; 3];
        assert_eq!(quantize(&[2.0; 3], 5, &mut c), 1);
        assert_eq!(c, [0; 3]);
    }
}
