//! Hard cases, bad input: random and mutated scene files, OBJ/MTL meshes, EXR/PNG/JPEG images
//! and RPF sample files go through every loader. No input may make a loader panic; every error
//! names the file it is about; errors inside a scene file carry its line and column, and OBJ
//! parse errors the offending line. Scenes that load are checked for the invariants the
//! renderer relies on (finite geometry with positive area, valid indices, sizes in range), but
//! never rendered here.
//!
//! The property tests run 28,100 cases in all (the `CASES_*` constants), in about 10 s in
//! release on two cores; the seed is fixed, so every run tries the same inputs and a failure is
//! reproducible. A failure prints the shrunk input; `PROPTEST_RNG_SEED=<u64>` tries other
//! inputs.
//!
//! Bugs these tests found, each with a hand-picked case below: tobj panicked on an MTL colour
//! with fewer than three numbers; a normal index near 2^64 / 3 wrapped to a valid one; an EXR
//! header claiming 10^9 x 512 pixels made the reader allocate terabytes and abort; a triangle
//! whose area overflows f32 kept a zero normal; a sphere light could emit nothing; an `l` line
//! with three vertices became a triangle; errors about a default `up` and about MTL textures
//! had no scene position.
//!
//! The position criterion for scene files:
//! - text that is not valid TOML (`toml::from_str::<toml::Table>` fails): the error has a
//!   position, always;
//! - valid TOML that is not a valid scene: the error has a position, except when the problem is
//!   a required top-level table that the file does not have at all (`[camera]`), which has no
//!   place in the text; its message then names the missing table;
//! - errors about a file the scene names (a texture, an OBJ, an MTL) point at the scene line
//!   that names it, and their message names that file too;
//! - a position is always inside the text (line <= number of lines + 1, column >= 1).

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::LazyLock;
use std::sync::atomic::{AtomicUsize, Ordering};

use proptest::collection::vec;
use proptest::prelude::*;
use proptest::sample::{Index, select};
use proptest::test_runner::TestCaseError;

mod common;

use noisefree::scene::mesh::{self, MeshPart};
use noisefree::scene::texture;
use noisefree::scene::{MaterialKind, Scene, SceneError, load_scene, load_scene_str};

// Cases per property; 10,000+ in all. Each property's share follows its cost per case.
const CASES_TOML_MUTATED: u32 = 8000;
const CASES_TOML_GENERATED: u32 = 5000;
const CASES_TOML_BYTES: u32 = 2000;
const CASES_OBJ: u32 = 4000;
const CASES_MTL: u32 = 1000;
const CASES_EXR: u32 = 4000;
const CASES_SKY_EXR: u32 = 100;
const CASES_PNG: u32 = 2000;
const CASES_JPEG: u32 = 1000;
const CASES_RPF: u32 = 1000;

fn config(cases: u32) -> ProptestConfig {
    // A fixed seed, so CI runs the same cases every time (a failure is reproducible); set
    // PROPTEST_RNG_SEED to explore other cases locally.
    let seed = std::env::var("PROPTEST_RNG_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0x6e6f_6973_6566_7265);
    ProptestConfig {
        cases,
        // No regression files in the source tree.
        failure_persistence: None,
        max_shrink_iters: 2000,
        rng_seed: proptest::test_runner::RngSeed::Fixed(seed),
        ..ProptestConfig::default()
    }
}

fn fixture(name: &str) -> PathBuf {
    common::repo_path("tests/scenes/bad_input").join(name)
}

/// The folder every case writes into: links to scenes/textures and scenes/models, so that the
/// bundled scenes' relative paths resolve, and copies of the fixture mesh.
static WORK: LazyLock<PathBuf> = LazyLock::new(|| {
    let d = common::tempdir("hard-input");
    for sub in ["textures", "models"] {
        std::os::unix::fs::symlink(common::repo_path("scenes").join(sub), d.join(sub)).unwrap();
    }
    std::fs::write(
        d.join("tri.obj"),
        std::fs::read(fixture("tri.obj")).unwrap(),
    )
    .unwrap();
    // map_Kd by absolute path, so that copies of the MTL in other folders find it too.
    let scenes = format!("{}/", common::repo_path("scenes").display());
    let mtl = read_text(&fixture("tri.mtl")).replace("../../../scenes/", &scenes);
    std::fs::write(d.join("tri.mtl"), mtl).unwrap();
    d
});

fn work() -> &'static Path {
    &WORK
}

/// A fresh path in the work folder (cases of all tests run in parallel).
fn fresh(stem: &str, ext: &str) -> PathBuf {
    static N: AtomicUsize = AtomicUsize::new(0);
    work().join(format!(
        "{stem}-{}.{ext}",
        N.fetch_add(1, Ordering::Relaxed)
    ))
}

fn read_text(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap()
}

/// Fixture paths point from tests/scenes/bad_input to scenes/; in the work folder the links do.
fn local_paths(text: &str) -> String {
    text.replace("../../../scenes/", "")
}

/// Runs `f`, turning a panic into a failed case that says what panicked.
fn no_panic<T>(what: &str, f: impl FnOnce() -> T) -> Result<T, TestCaseError> {
    catch_unwind(AssertUnwindSafe(f)).map_err(|p| {
        let msg = p
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| p.downcast_ref::<String>().cloned())
            .unwrap_or_default();
        TestCaseError::fail(format!("{what} panicked: {msg}"))
    })
}

// ---------------------------------------------------------------------------------------------
// Mutations

/// Text edits: positions are `Index`es, so they shrink and fit any length.
#[derive(Clone, Debug)]
enum Edit {
    Delete(Index, u8),
    Insert(Index, &'static str),
    DuplicateLine(Index),
    DeleteLine(Index),
    SwapLines(Index, Index),
    /// Replace the value of the n-th `key = value` line.
    ReplaceValue(Index, &'static str),
    /// Exchange the values of two `key = value` lines.
    SwapValues(Index, Index),
    /// Replace the n-th number.
    ReplaceNumber(Index, &'static str),
    /// Insert a whole line before the n-th line.
    InsertLine(Index, &'static str),
    Truncate(Index),
}

fn floor_char_boundary(s: &str, mut i: usize) -> usize {
    i = i.min(s.len());
    while !s.is_char_boundary(i) {
        i -= 1;
    }
    i
}

fn lines_of(s: &str) -> Vec<String> {
    s.split_inclusive('\n').map(str::to_string).collect()
}

fn value_lines(lines: &[String]) -> Vec<usize> {
    (0..lines.len())
        .filter(|&i| lines[i].contains('='))
        .collect()
}

fn set_value(line: &str, value: &str) -> String {
    let eq = line.find('=').unwrap();
    let end = if line.ends_with('\n') { "\n" } else { "" };
    format!("{}= {value}{end}", &line[..eq])
}

fn value_of(line: &str) -> String {
    let eq = line.find('=').unwrap();
    line[eq + 1..].trim().to_string()
}

/// Byte ranges of the numbers in `s` (a digit run with sign, point, exponent).
fn numbers(s: &str) -> Vec<std::ops::Range<usize>> {
    let b = s.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts = b[i].is_ascii_digit()
            || (matches!(b[i], b'-' | b'+') && b.get(i + 1).is_some_and(u8::is_ascii_digit));
        let word_before = i > 0 && (b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_');
        if starts && !word_before {
            let start = i;
            i += 1;
            while i < b.len()
                && (b[i].is_ascii_digit()
                    || matches!(b[i], b'.' | b'e' | b'E' | b'_')
                    || (matches!(b[i], b'-' | b'+') && matches!(b[i - 1], b'e' | b'E')))
            {
                i += 1;
            }
            out.push(start..i);
        } else {
            i += 1;
        }
    }
    out
}

fn apply_edits(text: &str, edits: &[Edit]) -> String {
    let mut s = text.to_string();
    for e in edits {
        match e {
            Edit::Delete(at, n) => {
                if !s.is_empty() {
                    let a = floor_char_boundary(&s, at.index(s.len()));
                    let b = floor_char_boundary(&s, a + *n as usize % 16 + 1);
                    s.replace_range(a..b, "");
                }
            }
            Edit::Insert(at, tok) => {
                let a = floor_char_boundary(&s, at.index(s.len() + 1));
                s.insert_str(a, tok);
            }
            Edit::Truncate(at) => {
                let a = floor_char_boundary(&s, at.index(s.len() + 1));
                s.truncate(a);
            }
            Edit::DuplicateLine(i) | Edit::DeleteLine(i) => {
                let mut l = lines_of(&s);
                if !l.is_empty() {
                    let k = i.index(l.len());
                    if matches!(e, Edit::DuplicateLine(_)) {
                        let mut dup = l[k].clone();
                        if !dup.ends_with('\n') {
                            dup.push('\n');
                            l[k].insert(0, '\n');
                        }
                        l.insert(k, dup);
                    } else {
                        l.remove(k);
                    }
                    s = l.concat();
                }
            }
            Edit::SwapLines(a, b) => {
                let mut l = lines_of(&s);
                if let Some(last) = l.last_mut()
                    && !last.ends_with('\n')
                {
                    last.push('\n');
                }
                if !l.is_empty() {
                    let (a, b) = (a.index(l.len()), b.index(l.len()));
                    l.swap(a, b);
                    s = l.concat();
                }
            }
            Edit::InsertLine(i, line) => {
                let mut l = lines_of(&s);
                let k = i.index(l.len() + 1);
                if k == l.len()
                    && let Some(last) = l.last_mut()
                    && !last.ends_with('\n')
                {
                    last.push('\n');
                }
                l.insert(k, format!("{line}\n"));
                s = l.concat();
            }
            Edit::ReplaceValue(i, v) => {
                let mut l = lines_of(&s);
                let vl = value_lines(&l);
                if !vl.is_empty() {
                    let k = vl[i.index(vl.len())];
                    l[k] = set_value(&l[k], v);
                    s = l.concat();
                }
            }
            Edit::SwapValues(a, b) => {
                let mut l = lines_of(&s);
                let vl = value_lines(&l);
                if !vl.is_empty() {
                    let (a, b) = (vl[a.index(vl.len())], vl[b.index(vl.len())]);
                    let (va, vb) = (value_of(&l[a]), value_of(&l[b]));
                    l[a] = set_value(&l[a], &vb);
                    l[b] = set_value(&l[b], &va);
                    s = l.concat();
                }
            }
            Edit::ReplaceNumber(i, v) => {
                let nums = numbers(&s);
                if !nums.is_empty() {
                    let r = nums[i.index(nums.len())].clone();
                    s.replace_range(r, v);
                }
            }
        }
    }
    s
}

fn edit(
    tokens: &'static [&'static str],
    values: &'static [&'static str],
    lines: &'static [&'static str],
) -> BoxedStrategy<Edit> {
    // Value-level edits weigh most: they get past the TOML parser into the scene checks.
    prop_oneof![
        1 => (any::<Index>(), any::<u8>()).prop_map(|(a, n)| Edit::Delete(a, n)),
        2 => (any::<Index>(), select(tokens)).prop_map(|(a, t)| Edit::Insert(a, t)),
        1 => any::<Index>().prop_map(Edit::DuplicateLine),
        1 => any::<Index>().prop_map(Edit::DeleteLine),
        1 => (any::<Index>(), any::<Index>()).prop_map(|(a, b)| Edit::SwapLines(a, b)),
        4 => (any::<Index>(), select(values)).prop_map(|(a, v)| Edit::ReplaceValue(a, v)),
        2 => (any::<Index>(), any::<Index>()).prop_map(|(a, b)| Edit::SwapValues(a, b)),
        4 => (any::<Index>(), select(values)).prop_map(|(a, v)| Edit::ReplaceNumber(a, v)),
        3 => (any::<Index>(), select(lines)).prop_map(|(a, l)| Edit::InsertLine(a, l)),
        1 => any::<Index>().prop_map(Edit::Truncate),
    ]
    .boxed()
}

/// Byte edits, for binary files and for text that need not stay UTF-8.
#[derive(Clone, Debug)]
enum ByteEdit {
    Flip(Index, u8),
    Set(Index, u8),
    /// Overwrite four bytes with an interesting little-endian u32.
    SetU32(Index, u32),
    Delete(Index, u16),
    Insert(Index, Vec<u8>),
    /// Copy a range over another place (repeats a structure).
    Copy(Index, Index, u16),
    Truncate(Index),
}

/// Edits that land near the start of a file, where the headers are, with a higher weight.
fn byte_edit() -> BoxedStrategy<ByteEdit> {
    let anywhere = any::<Index>();
    let interesting_u32 = prop_oneof![
        Just(0u32),
        Just(1),
        Just(2),
        Just(0x7f),
        Just(0xff),
        Just(0x8000),
        Just(0xffff),
        Just(0x10000),
        Just(0x7fff_ffff),
        Just(0x8000_0000),
        Just(0xffff_ffff),
        Just(0x4000_0000),
        Just(0x7f80_0000), // +inf as f32
        Just(0x7fc0_0000), // NaN as f32
        any::<u32>(),
    ];
    prop_oneof![
        3 => (anywhere.clone(), 0u8..8).prop_map(|(a, b)| ByteEdit::Flip(a, b)),
        2 => (anywhere.clone(), any::<u8>()).prop_map(|(a, b)| ByteEdit::Set(a, b)),
        3 => (anywhere.clone(), interesting_u32).prop_map(|(a, v)| ByteEdit::SetU32(a, v)),
        1 => (anywhere.clone(), any::<u16>()).prop_map(|(a, n)| ByteEdit::Delete(a, n)),
        1 => (anywhere.clone(), vec(any::<u8>(), 1..16)).prop_map(|(a, b)| ByteEdit::Insert(a, b)),
        1 => (anywhere.clone(), anywhere.clone(), any::<u16>())
            .prop_map(|(a, b, n)| ByteEdit::Copy(a, b, n)),
        1 => anywhere.prop_map(ByteEdit::Truncate),
    ]
    .boxed()
}

/// Applies byte edits; positions in the first `head` bytes are chosen for half of the edits
/// (`in_head`), where file headers live and mutations matter most.
fn apply_byte_edits(bytes: &[u8], edits: &[(bool, ByteEdit)], head: usize) -> Vec<u8> {
    let mut b = bytes.to_vec();
    for (in_head, e) in edits {
        let pos = |i: &Index, len: usize| {
            if *in_head {
                i.index(head.min(len).max(1))
            } else {
                i.index(len.max(1))
            }
        };
        match e {
            ByteEdit::Flip(i, bit) => {
                if !b.is_empty() {
                    let p = pos(i, b.len()).min(b.len() - 1);
                    b[p] ^= 1 << bit;
                }
            }
            ByteEdit::Set(i, v) => {
                if !b.is_empty() {
                    let p = pos(i, b.len()).min(b.len() - 1);
                    b[p] = *v;
                }
            }
            ByteEdit::SetU32(i, v) => {
                if b.len() >= 4 {
                    let p = pos(i, b.len()).min(b.len() - 4);
                    b[p..p + 4].copy_from_slice(&v.to_le_bytes());
                }
            }
            ByteEdit::Delete(i, n) => {
                if !b.is_empty() {
                    let p = pos(i, b.len()).min(b.len() - 1);
                    let e = (p + 1 + *n as usize % 64).min(b.len());
                    b.drain(p..e);
                }
            }
            ByteEdit::Insert(i, v) => {
                let p = pos(i, b.len() + 1).min(b.len());
                b.splice(p..p, v.iter().copied());
            }
            ByteEdit::Copy(from, to, n) => {
                if !b.is_empty() {
                    let f = from.index(b.len());
                    let t = pos(to, b.len()).min(b.len() - 1);
                    let n = (*n as usize % 256 + 1).min(b.len() - f).min(b.len() - t);
                    let chunk = b[f..f + n].to_vec();
                    b[t..t + n].copy_from_slice(&chunk);
                }
            }
            ByteEdit::Truncate(i) => {
                let p = pos(i, b.len() + 1).min(b.len());
                b.truncate(p);
            }
        }
    }
    b
}

fn byte_edits(max: usize) -> impl Strategy<Value = Vec<(bool, ByteEdit)>> {
    vec((any::<bool>(), byte_edit()), 1..max)
}

// ---------------------------------------------------------------------------------------------
// Scenes

/// Tokens inserted anywhere in a scene file.
const TOML_TOKENS: &[&str] = &[
    "[",
    "]",
    "[[",
    "]]",
    "=",
    "\"",
    "'",
    "'''",
    "\"\"\"",
    ",",
    "{",
    "}",
    "#",
    "\n",
    "\r\n",
    "\r",
    ".",
    "\\",
    "\\u00e9",
    "\\uD800",
    "\\U0010FFFF",
    "\\x",
    " ",
    "\t",
    "\u{0}",
    "\u{7f}",
    "\u{feff}",
    "\u{202e}",
    "é",
    "𝔘",
    "日本",
    "1e999",
    "nan",
    "-inf",
    "+inf",
    "-0.0",
    "9223372036854775808",
    "0x",
    "0b102",
    "0o8",
    "1__0",
    "1979-05-27T07:32:00Z",
    "07:32:00",
    "true",
    "false",
    "[render]",
    "[camera]",
    "[[mesh]]",
    "[[material]]",
    "[[sphere]]",
    "[[light]]",
    "[[texture]]",
    "[filter]",
    "[render.x]",
    "camera = 1",
    "a.b.c = 1",
];

/// Values put in place of a value or a number.
const TOML_VALUES: &[&str] = &[
    "0",
    "1",
    "-1",
    "2",
    "3",
    "0.5",
    "-0.5",
    "1e999",
    "-1e999",
    "nan",
    "-nan",
    "inf",
    "-inf",
    "+inf",
    "-0.0",
    "1e-45",
    "1e-50",
    "3.5e38",
    "-3.5e38",
    "65535",
    "32768",
    "32769",
    "16777217",
    "4294967295",
    "4294967296",
    "9223372036854775807",
    "-9223372036854775808",
    "\"text\"",
    "\"\"",
    "\"é𝔘\u{202e}\"",
    "\".\"",
    "\"/\"",
    "\"..\"",
    "\"/dev/null\"",
    "\"textures\"",
    "\"models\"",
    "\"models/cornell_box.mtl\"",
    "\"textures/sky.exr\"",
    "\"textures/checker.png\"",
    "\"tri.obj\"",
    "\"missing.obj\"",
    "\"box\"",
    "\"quad\"",
    "\"diffuse\"",
    "\"specular\"",
    "\"glass\"",
    "\"metal\"",
    "\"emitter\"",
    "\"sphere\"",
    "\"infinite\"",
    "\"ddf\"",
    "\"rpf\"",
    "\"atrous\"",
    "\"none\"",
    "\"outdoor\"",
    "true",
    "false",
    "[]",
    "[1]",
    "[1, 2]",
    "[1, 2, 3]",
    "[1, 2, 3, 4]",
    "[0, 0, 0]",
    "[0, 1, 0]",
    "[-1, -1, -1]",
    "[nan, nan, nan]",
    "[1e999, 0, 0]",
    "[inf, 0, 0]",
    "[1, 1, 1, 1, 1]",
    "[\"a\", \"b\", \"c\"]",
    "[[1, 2, 3]]",
    "{}",
    "{ x = 1 }",
    "1979-05-27",
    "'literal'",
    "\"\"\"multi\nline\"\"\"",
    "[1, \"a\", true]",
];

/// Whole lines inserted into a scene file.
const TOML_LINES: &[&str] = &[
    "unknown_field = 1",
    "radiuss = 2",
    "[render]",
    "[camera]",
    "[[texture]]",
    "[[material]]",
    "[[sphere]]",
    "[[mesh]]",
    "[[light]]",
    "[filter]",
    "[bogus]",
    "[[camera]]",
    "width = 0",
    "height = 100000",
    "spp = 0",
    "max_depth = -1",
    "seed = -1",
    "fov = 180",
    "fov = 0",
    "lens_radius = 1",
    "autofocus = true",
    "focal_distance = 0",
    "up = [0, 0, 0]",
    "target = [0, 1, 4]",
    "name = \"checker\"",
    "name = \"floor\"",
    "type = \"sphere\"",
    "type = \"infinite\"",
    "type = \"metal\"",
    "type = \"emitter\"",
    "file = \"textures\"",
    "file = \"tri.obj\"",
    "file = \"models/cornell_box.obj\"",
    "file = \"textures/sky.exr\"",
    "file = \"\"",
    "generator = \"box\"",
    "generator = \"teapot\"",
    "material = \"nope\"",
    "material = \"floor\"",
    "texture = \"checker\"",
    "texture = \"nope\"",
    "scale = 0",
    "scale = [1, 2]",
    "scale = 1e-30",
    "scale = 1e30",
    "rotate = [nan, 0, 0]",
    "translate = [1e39, 0, 0]",
    "center = [0, 0, 0]",
    "radius = -1",
    "radius = 0",
    "emission = [1, 1, 1]",
    "emission = [-1, 0, 0]",
    "color = [0.5, 0.5, 0.5]",
    "color = \"red\"",
    "gain = -1",
    "uv_scale = [inf, 1]",
    "exponent = -2",
    "ior_inside = 0",
    "kw = -1",
    "kw = 4294967296",
    "sigma_f = [1, 2]",
    "method = 3",
    "method = \"atrous\"",
    "[filter.ddf]",
    "[filter.atrous]",
    "[filter.nope]",
    "iterations = 99",
    "sigma_color = \"auto\"",
    "sky = \"maybe\"",
    "x = 1\nx = 2",
    "\u{feff}",
    "# comment é𝔘",
];

/// Small valid scenes besides the bundled ones.
const SMALL_SCENES: &[(&str, &str)] = &[
    (
        "tiny",
        "[camera]\norigin = [0, 0, 5]\ntarget = [0, 0, 0]\n\n[[material]]\nname = \"w\"\n\
         type = \"diffuse\"\n\n[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"w\"\n",
    ),
    (
        "inline",
        "render = { width = 4, height = 4, spp = 1 }\ncamera = { origin = [0, 0, 5], target = \
         [0, 0, 0] }\nmaterial = [{ name = \"m\", type = \"metal\", exponent = 5 }]\n\
         mesh = [{ generator = \"box\", material = \"m\", scale = [1, 2, 3] }]\n\
         light = [{ type = \"infinite\", texture = \"sky\" }]\n\
         texture = [{ name = \"sky\", file = \"textures/checker.png\" }]\n",
    ),
    (
        "obj",
        "[camera]\norigin = [0, 1, 3]\ntarget = [0, 1, 0]\n\n[[mesh]]\n\
         file = \"models/cornell_box.obj\"\nrotate = [0, 180, 0]\n",
    ),
    (
        "filters",
        "[camera]\norigin = [0, 0, 5]\ntarget = [0, 0, 0]\n\n[filter]\nmethod = \"atrous\"\n\n\
         [filter.ddf]\nkw = 7\nsky = \"auto\"\n\n[filter.atrous]\niterations = 3\n\
         sigma_color = 0.5\n\n[filter.rpf]\nbox_sizes = [17, 7]\n",
    ),
];

/// The bundled scenes, with the two large generators replaced by `box` so that a case loads in
/// milliseconds (the large generators are exercised by their own tests).
static SCENES: LazyLock<Vec<(String, String)>> = LazyLock::new(|| {
    let mut v: Vec<(String, String)> = Vec::new();
    let files = common::bundled_scenes();
    assert!(!files.is_empty(), "no bundled scenes found");
    for f in files {
        let text = read_text(&f)
            .replace("\"conference_room\"", "\"box\"")
            .replace("\"airplane\"", "\"box\"");
        v.push((f.file_stem().unwrap().to_string_lossy().into_owned(), text));
    }
    v.push((
        "minimal".into(),
        local_paths(&read_text(&fixture("minimal.toml"))),
    ));
    for (name, text) in SMALL_SCENES {
        v.push((name.to_string(), text.to_string()));
    }
    v
});

fn scene_index() -> impl Strategy<Value = usize> {
    0..SCENES.len()
}

/// Whether an error without a position is allowed: see the module docs.
fn position_may_be_missing(text: &str, e: &SceneError) -> bool {
    toml::from_str::<toml::Table>(text).is_ok_and(|t| !t.contains_key("camera"))
        && e.message.contains("camera")
}

/// The checks every scene loader result must pass.
fn check_scene(
    path: &Path,
    text: Option<&str>,
    r: &Result<Scene, SceneError>,
) -> Result<(), TestCaseError> {
    match r {
        Err(e) => {
            prop_assert_eq!(&e.path, path, "the error must name the scene file: {}", e);
            let shown = e.to_string();
            prop_assert!(shown.contains(&path.display().to_string()), "{}", shown);
            prop_assert!(!e.message.trim().is_empty(), "an empty message");
            if let Some(text) = text {
                match e.position {
                    Some((line, col)) => {
                        let lines = text.split('\n').count();
                        prop_assert!(
                            line >= 1 && line <= lines && col >= 1,
                            "position {}:{} outside the text ({} lines): {}",
                            line,
                            col,
                            lines,
                            e
                        );
                        if let Some(l) = text.split('\n').nth(line - 1) {
                            prop_assert!(
                                col <= l.chars().count() + 1,
                                "column {} past the end of line {}: {}",
                                col,
                                line,
                                e
                            );
                        }
                    }
                    None => prop_assert!(
                        position_may_be_missing(text, e),
                        "an error inside the scene text without a position: {}",
                        e
                    ),
                }
            }
        }
        Ok(s) => {
            check_scene_invariants(s)?;
            check_filter_tables(path, s)?;
        }
    }
    Ok(())
}

/// A loaded scene's `[filter.<name>]` tables go through the filter registry as `render` takes
/// them: no panic, and an error names the scene file and the line of the table it is about.
fn check_filter_tables(path: &Path, s: &Scene) -> Result<(), TestCaseError> {
    use noisefree::filters::{FilterRequest, Registry};
    let shown = path.display().to_string();
    let request = FilterRequest {
        scene: s.filter.settings.clone(),
        scene_origin: shown.clone(),
        scene_lines: s.filter.lines.clone(),
        ..Default::default()
    };
    let info = noisefree::render::SceneInfo::unknown();
    let r = no_panic("Registry::configure_all", || {
        Registry::builtin().configure_all(&request, &info)
    })?;
    if let Err(e) = r {
        let t = anyhow_text(&e);
        prop_assert!(t.contains(&shown), "{}", t);
        let at_a_table = s
            .filter
            .lines
            .values()
            .any(|l| t.contains(&format!("{shown}:{l}: [filter.")));
        prop_assert!(at_a_table, "no table line in: {}", t);
    }
    Ok(())
}

/// What the renderer relies on in a loaded scene.
fn check_scene_invariants(s: &Scene) -> Result<(), TestCaseError> {
    let r = &s.render;
    prop_assert!((1..=32768).contains(&r.width) && (1..=32768).contains(&r.height));
    prop_assert!(r.spp >= 1);
    let c = &s.camera;
    prop_assert!(c.origin.is_finite() && c.target.is_finite() && c.up.is_finite());
    prop_assert!((c.target - c.origin).length() > 0.0);
    prop_assert!(c.fov_degrees > 0.0 && c.fov_degrees < 180.0);
    prop_assert!(c.lens_radius >= 0.0 && c.lens_radius.is_finite());
    prop_assert!(c.focal_distance.is_none_or(|f| f > 0.0 && f.is_finite()));
    prop_assert!(c.lens_radius == 0.0 || c.focal_distance.is_some() || c.autofocus);
    for t in &s.textures {
        prop_assert!(t.width >= 1 && t.height >= 1);
        prop_assert_eq!(t.texels.len(), t.width as usize * t.height as usize);
        prop_assert!(t.texels.iter().flatten().all(|v| v.is_finite()));
        prop_assert!(t.uv_scale.is_finite() && t.uv_shift.is_finite());
    }
    let ok3 = |v: glam::Vec3| v.is_finite() && v.min_element() >= 0.0;
    for m in &s.materials {
        prop_assert!(ok3(m.emission), "{:?}", m);
        match &m.kind {
            MaterialKind::Diffuse { color, texture } => {
                prop_assert!(ok3(*color));
                prop_assert!(texture.is_none_or(|t| (t as usize) < s.textures.len()));
            }
            MaterialKind::Specular { color } => prop_assert!(ok3(*color)),
            MaterialKind::Glass {
                reflect_color,
                refract_color,
                ior_outside,
                ior_inside,
            } => {
                prop_assert!(ok3(*reflect_color) && ok3(*refract_color));
                prop_assert!(*ior_outside > 0.0 && ior_outside.is_finite());
                prop_assert!(*ior_inside > 0.0 && ior_inside.is_finite());
            }
            MaterialKind::Metal { color, exponent } => {
                prop_assert!(ok3(*color));
                // The loader's documented range: a normalised Phong lobe needs exponent > -1.
                prop_assert!(*exponent > -1.0 && exponent.is_finite(), "{:?}", m);
            }
            MaterialKind::Emitter => prop_assert!(m.emission.max_element() > 0.0),
        }
    }
    let nm = s.materials.len();
    for sp in &s.spheres {
        prop_assert!(sp.center.is_finite() && sp.radius > 0.0 && sp.radius.is_finite());
        prop_assert!((sp.material as usize) < nm);
    }
    for t in &s.triangles {
        prop_assert!(t.p.iter().all(|p| p.is_finite()), "{:?}", t);
        prop_assert!(
            t.area() > 0.0 && t.area().is_finite(),
            "a triangle with zero or infinite area was kept: {:?}",
            t
        );
        prop_assert!(
            t.n.iter()
                .all(|n| n.is_finite() && (n.length() - 1.0).abs() < 1e-3),
            "a bad normal was kept: {:?}",
            t
        );
        prop_assert!(t.uv.iter().all(|u| u.is_finite()));
        prop_assert!((t.material as usize) < nm);
    }
    if let Some(env) = &s.environment {
        prop_assert!(ok3(env.radiance));
        prop_assert!(env.texture.is_none_or(|t| (t as usize) < s.textures.len()));
        prop_assert!(env.uv_scale.is_finite() && env.uv_shift.is_finite());
    }
    Ok(())
}

/// Loads scene text from `name.toml` in the work folder and checks the result.
fn check_scene_text(name: &str, text: &str) -> Result<(), TestCaseError> {
    let path = work().join(format!("{name}.toml"));
    let r = no_panic("load_scene_str", || load_scene_str(&path, text))?;
    check_scene(&path, Some(text), &r)
}

/// Values of the type a field expects, ordinary and extreme.
fn typed_values(key: &str) -> &'static [&'static str] {
    const INT: &[&str] = &[
        "0",
        "1",
        "-1",
        "3",
        "8",
        "32768",
        "32769",
        "16777216",
        "16777217",
        "4294967295",
        "4294967296",
        "9223372036854775807",
        "-9223372036854775808",
    ];
    const FLOAT: &[&str] = &[
        "0", "1", "-1", "0.5", "2", "45", "180", "179.999", "1e-45", "1e-30", "1e30", "3.5e38",
        "-3.5e38", "nan", "inf", "-inf", "-0.0",
    ];
    const VEC3: &[&str] = &[
        "[0, 0, 0]",
        "[0, 1, 0]",
        "[1, 1, 1]",
        "[-1, 0, 0]",
        "[0, 0, 5]",
        "[0, 0, -5]",
        "[10, 10, 10]",
        "[nan, 0, 0]",
        "[0, inf, 0]",
        "[3.5e38, 0, 0]",
        "[1e-45, 0, 0]",
        "[0, 1e30, 0]",
        "[-1e30, 1e30, 0]",
    ];
    const VEC2: &[&str] = &[
        "[1, 1]",
        "[0, 0]",
        "[nan, 1]",
        "[inf, 0]",
        "[1e30, 1e30]",
        "[-1, 2]",
    ];
    const VEC5: &[&str] = &[
        "[1, 1, 1, 1, 1]",
        "[0, 0, 0, 0, 0]",
        "[nan, 1, 1, 1, 1]",
        "[-1, 1, 1, 1, 1]",
        "[inf, 1, 1, 1, 1]",
        "[1e30, 1, 1, 1, 1]",
    ];
    const SCALE: &[&str] = &[
        "1",
        "0",
        "-1",
        "1e-30",
        "1e30",
        "nan",
        "[1, 1, 1]",
        "[1, 0, 1]",
        "[1e-30, 1e-30, 1e-30]",
        "[inf, 1, 1]",
        "[-1, 1, 1]",
    ];
    const BOOL: &[&str] = &["true", "false"];
    const AUTO_BOOL: &[&str] = &["true", "false", "\"auto\"", "\"on\""];
    const AUTO_FLOAT: &[&str] = &["\"auto\"", "0.5", "0", "-1", "nan", "inf", "1e30", "\"x\""];
    const BOXES: &[&str] = &["[55, 35, 17, 7]", "[]", "[0]", "[1024]", "[3, -1]", "[1e3]"];
    const NAME: &[&str] = &[
        "\"a\"",
        "\"b\"",
        "\"\"",
        "\"é𝔘\"",
        "\"a\\u0000\"",
        "\"checker\"",
    ];
    const TYPE: &[&str] = &[
        "\"diffuse\"",
        "\"specular\"",
        "\"glass\"",
        "\"metal\"",
        "\"emitter\"",
        "\"sphere\"",
        "\"infinite\"",
        "\"plastic\"",
    ];
    const FILE: &[&str] = &[
        "\"tri.obj\"",
        "\"textures/checker.png\"",
        "\"textures/sky.exr\"",
        "\"models/cornell_box.obj\"",
        "\"models\"",
        "\"\"",
        "\"missing.png\"",
        "\"tri.mtl\"",
        "\"/dev/null\"",
        "\"textures/checker.png/\"",
        "\"./tri.obj\"",
    ];
    const GENERATOR: &[&str] = &["\"box\"", "\"quad\"", "\"teapot\"", "\"\""];
    const WORD: &[&str] = &[
        "\"indoor\"",
        "\"outdoor\"",
        "\"ddf\"",
        "\"rpf\"",
        "\"atrous\"",
        "\"none\"",
        "\"thesis\"",
        "\"difference\"",
        "\"naive\"",
        "\"vector\"",
        "\"rows\"",
        "\"packed\"",
        "\"scalar\"",
        "\"auto\"",
        "\"current\"",
        "\"original\"",
        "\"other\"",
    ];
    match key {
        "width" | "height" | "spp" | "max_depth" | "seed" | "kw" | "work_group" | "iterations"
        | "mi_buckets" => INT,
        "fov" | "lens_radius" | "focal_distance" | "ior_outside" | "ior_inside" | "exponent"
        | "radius" | "gain" | "sigma_dc" | "sigma_ic" | "clamp" => FLOAT,
        "sigma_color" | "sigma_normal" | "sigma_position" | "sigma2_8" => AUTO_FLOAT,
        "box_sizes" => BOXES,
        "origin" | "target" | "up" | "color" | "reflect_color" | "refract_color" | "emission"
        | "center" | "rotate" | "translate" => VEC3,
        "uv_scale" | "uv_shift" => VEC2,
        "sigma_f" | "variance_scale" => VEC5,
        "scale" => SCALE,
        "russian_roulette" | "next_event_estimation" | "autofocus" | "holes" | "demodulate" => BOOL,
        "texture2" | "sky" => AUTO_BOOL,
        "name" | "material" | "texture" => NAME,
        "type" => TYPE,
        "file" => FILE,
        "generator" => GENERATOR,
        "setting" | "method" | "direction" | "variant" | "range_colors" => WORD,
        _ => &[],
    }
}

/// A random scene: each table at most once (`[render]`, `[camera]`, `[filter]` and its
/// `[filter.<name>]` tables) or a few times
/// (the arrays of tables), with keys mostly of that table (sometimes any key, sometimes an
/// unknown one) and values from [`TOML_VALUES`]; with or without a valid camera.
fn generated_scene() -> impl Strategy<Value = String> {
    const TABLES: &[(&str, &[&str])] = &[
        (
            "[render]",
            &[
                "width",
                "height",
                "spp",
                "max_depth",
                "seed",
                "russian_roulette",
                "next_event_estimation",
                "setting",
                "clamp",
            ],
        ),
        (
            "[camera]",
            &[
                "origin",
                "target",
                "up",
                "fov",
                "lens_radius",
                "focal_distance",
                "autofocus",
            ],
        ),
        ("[[texture]]", &["name", "file", "uv_scale", "uv_shift"]),
        (
            "[[material]]",
            &[
                "name",
                "type",
                "color",
                "texture",
                "reflect_color",
                "refract_color",
                "ior_outside",
                "ior_inside",
                "exponent",
                "emission",
            ],
        ),
        ("[[sphere]]", &["center", "radius", "material"]),
        (
            "[[mesh]]",
            &[
                "file",
                "generator",
                "seed",
                "material",
                "scale",
                "rotate",
                "translate",
            ],
        ),
        (
            "[[light]]",
            &[
                "type", "center", "radius", "emission", "texture", "color", "gain", "uv_scale",
                "uv_shift",
            ],
        ),
        // `method`, and sometimes a setting written flat under [filter] (an error that says
        // where settings go).
        (
            "[filter]",
            &["method", "method", "method", "kw", "sigma_dc"],
        ),
        (
            "[filter.ddf]",
            &[
                "kw",
                "holes",
                "sigma_dc",
                "sigma_ic",
                "sigma_f",
                "variance_scale",
                "direction",
                "texture2",
                "sky",
                "variant",
                "work_group",
            ],
        ),
        (
            "[filter.atrous]",
            &[
                "iterations",
                "sigma_color",
                "sigma_normal",
                "sigma_position",
                "demodulate",
                "variant",
            ],
        ),
        (
            "[filter.rpf]",
            &[
                "sigma2_8",
                "seed",
                "box_sizes",
                "mi_buckets",
                "range_colors",
            ],
        ),
        ("[filter.bogus]", &["kw", "iterations"]),
    ];
    const OTHER_KEYS: &[&str] = &["bogus", "\"quoted key\"", "a.b", "type", "name", "width"];
    // The fields a table needs; each is there in most cases.
    fn required(header: &str) -> &'static [&'static str] {
        match header {
            "[camera]" => &["origin", "target"],
            "[[texture]]" => &["name", "file"],
            "[[material]]" => &["name", "type"],
            "[[sphere]]" => &["center", "radius", "material"],
            "[[mesh]]" => &["generator"],
            "[[light]]" => &["type"],
            _ => &[],
        }
    }
    // (own or other key, which key, typed value or any, which typed value, any value)
    let entry = (
        0u8..20,
        any::<Index>(),
        0u8..12,
        any::<usize>(),
        select(TOML_VALUES),
    );
    let table = (0..TABLES.len(), any::<u32>(), vec(entry, 0..6)).prop_map(|(t, mask, entries)| {
        let (header, keys) = TABLES[t];
        let mut used = std::collections::HashSet::new();
        let mut s = format!("{header}\n");
        // Mostly a value of the field's type (extreme or not), sometimes anything.
        let mut add = |key: &'static str, typed: u8, value: usize, any_value: &str| {
            let values = typed_values(key);
            let value = if typed > 0 && !values.is_empty() {
                values[value % values.len()]
            } else {
                any_value
            };
            if used.insert(key) {
                s.push_str(&format!("{key} = {value}\n"));
            }
        };
        // Each required field is there in 15 cases out of 16.
        for (i, key) in required(header).iter().enumerate() {
            if (mask >> (4 * i)) & 15 != 0 {
                add(key, 1, mask as usize * 7 + i, "");
            }
        }
        for (how, key, typed, value, any_value) in entries {
            let key = if how < 19 {
                keys[key.index(keys.len())]
            } else {
                OTHER_KEYS[key.index(OTHER_KEYS.len())]
            };
            add(key, typed, value, any_value);
        }
        (t, s)
    });
    (proptest::bool::weighted(0.9), vec(table, 1..6)).prop_map(|(camera, tables)| {
        let mut s = String::new();
        let mut once = std::collections::HashSet::new();
        if camera {
            s.push_str("[camera]\norigin = [0, 0, 5]\ntarget = [0, 0, 0]\n\n");
            once.insert(1);
        }
        for (t, text) in tables {
            // [render], [camera] and the [filter] tables may appear only once.
            if matches!(t, 0 | 1 | 7..) && !once.insert(t) {
                continue;
            }
            s.push_str(&text);
            s.push('\n');
        }
        s
    })
}

proptest! {
    #![proptest_config(config(CASES_TOML_MUTATED))]
    /// Bundled and small scenes, edited by up to six text mutations.
    #[test]
    fn mutated_scene_text_never_panics_and_errors_have_positions(
        i in scene_index(),
        edits in vec(edit(TOML_TOKENS, TOML_VALUES, TOML_LINES), 1..5),
    ) {
        let (name, text) = &SCENES[i];
        let text = apply_edits(text, &edits);
        check_scene_text(name, &text)?;
    }
}

proptest! {
    #![proptest_config(config(CASES_TOML_GENERATED))]
    /// Scenes made of random tables, keys and values.
    #[test]
    fn generated_scene_text_never_panics_and_errors_have_positions(text in generated_scene()) {
        check_scene_text("generated", &text)?;
    }
}

proptest! {
    #![proptest_config(config(CASES_TOML_BYTES))]
    /// Scene files with byte-level damage (invalid UTF-8, NUL bytes), read from disk.
    #[test]
    fn damaged_scene_files_never_panic_and_errors_name_the_file(
        i in scene_index(),
        edits in byte_edits(5),
    ) {
        let (_, text) = &SCENES[i];
        let bytes = apply_byte_edits(text.as_bytes(), &edits, 4096);
        let path = fresh("damaged", "toml");
        std::fs::write(&path, &bytes).unwrap();
        let r = no_panic("load_scene", || load_scene(&path))?;
        let text = std::str::from_utf8(&bytes).ok();
        if text.is_none() {
            let e = r.as_ref().err();
            prop_assert!(e.is_some(), "invalid UTF-8 was accepted");
            prop_assert!(e.unwrap().position.is_some(), "{}", e.unwrap());
        }
        check_scene(&path, text, &r)?;
        std::fs::remove_file(&path).unwrap();
    }
}

// ---------------------------------------------------------------------------------------------
// OBJ and MTL

const OBJ_TOKENS: &[&str] = &[
    "v",
    "vt",
    "vn",
    "vp",
    "f",
    "l",
    "p",
    "o",
    "g",
    "s",
    "usemtl",
    "mtllib",
    " ",
    "\n",
    "\r\n",
    "\t",
    "#",
    "\\\n",
    "/",
    "//",
    "1/",
    "/1",
    "1//1",
    "1/1/1/1",
    "0",
    "-0",
    "1",
    "-1",
    "-4",
    "9",
    "-99",
    "4294967296",
    "9223372036854775807",
    "-9223372036854775808",
    "6148914691236517207",
    "nan",
    "inf",
    "-inf",
    "1e39",
    "1e-45",
    "0x1",
    "é",
    "\u{0}",
    "\u{feff}",
    "\u{fffd}",
    "1.5.5",
];

const OBJ_VALUES: &[&str] = &[
    "0",
    "1",
    "-1",
    "2",
    "3",
    "4",
    "5",
    "-5",
    "99",
    "nan",
    "inf",
    "-inf",
    "1e39",
    "-0",
    "x",
    "",
    "4294967297",
    "9223372036854775807",
    "6148914691236517207",
];

const OBJ_LINES: &[&str] = &[
    "v 0 0 0",
    "v 1 1 1 0",
    "v 1 1 1 1 0 0",
    "v nan nan nan",
    "v 1 2",
    "vt 0.5 0.5",
    "vt 1",
    "vn 0 0 0",
    "vn nan 0 1",
    "vn 1 0",
    "f 1 2 3",
    "f 1 1 1",
    "f 1 2",
    "f 1",
    "f 0 1 2",
    "f 1 2 99",
    "f -1 -2 -3",
    "f -99 1 2",
    "f 1/1 2/2 3/3",
    "f 1//1 2//1 3//1",
    "f 1/1/1 2/2/1 3/3/1",
    "f 1/99/1 2/1/1 3/1/1",
    "f 1//6148914691236517207 2//1 3//1",
    "f 1/9223372036854775807 2/1 3/1",
    "f 1 2 3 4 5 6 7 8",
    "f a b c",
    "l 1 2",
    "p 1",
    "o",
    "o object",
    "g group",
    "usemtl",
    "usemtl tiles",
    "usemtl shiny",
    "usemtl light",
    "usemtl glassy",
    "usemtl missing",
    "mtllib tri.mtl",
    "mtllib missing.mtl",
    "mtllib",
    "s 1",
];

const MTL_LINES: &[&str] = &[
    "newmtl",
    "newmtl tiles",
    "newmtl extra",
    "Kd 1 1",
    "Kd",
    "Kd x y z",
    "Kd nan 0 0",
    "Ka 1",
    "Ks 1 1",
    "Ks 2 2 2",
    "Ke 1",
    "Ke 5 5 5",
    "Ke -5 5 5",
    "Ns",
    "Ns -1",
    "Ns nan",
    "Ni 0",
    "d 0.5",
    "d",
    "Tr 0.5",
    "illum 2",
    "illum x",
    "map_Kd",
    "map_Kd missing.png",
    "map_Kd textures",
    "map_Kd textures/sky.exr",
    "map_Kd textures/checker.png",
    "map_Kd tri.obj",
    "map_Ks textures/checker.png",
    "map_d x.png",
];

fn obj_base() -> impl Strategy<Value = usize> {
    0..OBJ_BASES.len()
}

static OBJ_BASES: LazyLock<Vec<String>> = LazyLock::new(|| {
    vec![
        read_text(&common::repo_path("scenes/models/cornell_box.obj"))
            .replace("mtllib cornell_box.mtl", "mtllib tri.mtl"),
        read_text(&fixture("tri.obj")),
        read_text(&fixture("degenerate.obj")),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvn 0 0 1\nvt 0 0\nf 1/1/1 2/1/1 3/1/1\nf -1 -2 -3\n"
            .to_string(),
    ]
});

/// A scene that uses `obj` (a file in the work folder) without and with a material override.
fn scene_for_obj(obj: &str, override_material: bool) -> String {
    format!(
        "[camera]\norigin = [0, 0, 5]\ntarget = [0, 0, 0]\n\n[[material]]\nname = \"grey\"\n\
         type = \"diffuse\"\n\n[[mesh]]\nfile = \"{obj}\"\n{}",
        if override_material {
            "material = \"grey\"\n"
        } else {
            ""
        }
    )
}

/// The line `position` points at, if any.
fn line_at(text: &[u8], line: usize) -> Option<String> {
    String::from_utf8_lossy(text)
        .lines()
        .nth(line.checked_sub(1)?)
        .map(str::to_string)
}

/// Loads OBJ bytes (with the MTL file `mtl`) in memory and through a scene, and checks both.
fn check_obj(obj: &[u8], mtl: &Path) -> Result<(), TestCaseError> {
    let obj_path = fresh("mesh", "obj");
    let opener = |_name: &Path| {
        let f = std::fs::File::open(mtl).map_err(|e| SceneError::new(mtl, e.to_string()))?;
        Ok((mtl.to_path_buf(), std::io::BufReader::new(f)))
    };
    let r = no_panic("load_obj_bytes", || {
        mesh::load_obj_bytes(&obj_path, obj, &opener)
    })?;
    match &r {
        Err(e) => {
            let shown = e.to_string();
            prop_assert!(!e.message.trim().is_empty());
            if e.path == mtl {
                prop_assert!(
                    shown.contains(&obj_path.display().to_string()),
                    "an MTL error must name the OBJ file that uses it: {}",
                    shown
                );
            } else {
                prop_assert_eq!(&e.path, &obj_path, "{}", shown);
            }
            prop_assert!(shown.contains(&e.path.display().to_string()));
            if e.path == obj_path {
                check_obj_position(obj, e)?;
            }
        }
        Ok(parts) => check_parts(parts)?,
    }

    // The same mesh through a scene file: the scene error names the scene and its line, and
    // the mesh file; a loaded scene passes the invariants.
    std::fs::write(&obj_path, obj).unwrap();
    let name = obj_path.file_name().unwrap().to_string_lossy().into_owned();
    // The MTL is found next to the OBJ, by the name in `mtllib`.
    let mtl_copy = work().join(format!("{name}.d"));
    std::fs::create_dir_all(&mtl_copy).unwrap();
    for lib in ["tri.mtl", "cornell_box.mtl"] {
        std::fs::copy(mtl, mtl_copy.join(lib)).unwrap();
    }
    let obj_in_dir = mtl_copy.join("mesh.obj");
    std::fs::rename(&obj_path, &obj_in_dir).unwrap();
    for override_material in [false, true] {
        let text = scene_for_obj(&format!("{name}.d/mesh.obj"), override_material);
        let scene_path = work().join("obj_scene.toml");
        let r = no_panic("load_scene_str with an OBJ", || {
            load_scene_str(&scene_path, &text)
        })?;
        check_scene(&scene_path, Some(&text), &r)?;
        if let Err(e) = &r
            && is_mesh_error(e)
        {
            prop_assert!(
                e.message.contains("mesh.obj") || e.message.contains("tri.mtl"),
                "the error must name the mesh file: {}",
                e
            );
        }
    }
    std::fs::remove_dir_all(&mtl_copy).unwrap();
    Ok(())
}

fn is_mesh_error(e: &SceneError) -> bool {
    e.message.starts_with("mesh ")
}

/// An OBJ error names the offending line (every error about the OBJ text is about a line),
/// and that line exists; errors that tobj reports by kind point at a line of that kind.
fn check_obj_position(obj: &[u8], e: &SceneError) -> Result<(), TestCaseError> {
    let text = String::from_utf8_lossy(obj);
    let (line, _) = e
        .position
        .ok_or_else(|| TestCaseError::fail(format!("an OBJ error without a line: {e}\n{text}")))?;
    let l = line_at(obj, line);
    prop_assert!(
        l.is_some() || (line == text.lines().count() + 1 && obj.ends_with(b"\n")),
        "line {} is past the end: {}\n{}",
        line,
        e,
        text
    );
    let kinds: &[(&str, &str)] = &[
        ("invalid OBJ: face", "f"),
        ("invalid OBJ: position", "v"),
        ("invalid OBJ: normal", "vn"),
        ("invalid OBJ: texcoord", "vt"),
        ("invalid OBJ: a vertex", "v"),
        ("invalid OBJ: the vertex", "v"),
        ("invalid OBJ: a texture coordinate", "vt"),
        ("invalid OBJ: a normal", "vn"),
        ("invalid OBJ: corner", "f"),
    ];
    for (prefix, keyword) in kinds {
        if e.message.starts_with(prefix) {
            let l = l.clone().unwrap_or_default();
            let first = l.split_whitespace().next().unwrap_or("");
            let ok = first == *keyword || (*keyword == "f" && first == "l");
            prop_assert!(
                ok,
                "line {} ({:?}) is not a `{}` line: {}\n{}",
                line,
                l,
                keyword,
                e,
                text
            );
        }
    }
    Ok(())
}

fn check_parts(parts: &[MeshPart]) -> Result<(), TestCaseError> {
    for p in parts {
        let n = p.positions.len();
        prop_assert!(p.indices.iter().flatten().all(|&i| (i as usize) < n));
        prop_assert!(p.normals.is_empty() || p.normals.len() == n);
        prop_assert!(p.uvs.is_empty() || p.uvs.len() == n);
    }
    Ok(())
}

proptest! {
    #![proptest_config(config(CASES_OBJ))]
    /// OBJ text with text and byte mutations, loaded alone and through a scene.
    #[test]
    fn mutated_obj_never_panics_and_errors_name_file_and_line(
        i in obj_base(),
        edits in vec(edit(OBJ_TOKENS, OBJ_VALUES, OBJ_LINES), 0..6),
        bytes in prop::option::weighted(0.2, byte_edits(3)),
    ) {
        let text = apply_edits(&OBJ_BASES[i], &edits);
        let obj = match bytes {
            Some(b) => apply_byte_edits(text.as_bytes(), &b, 256),
            None => text.into_bytes(),
        };
        check_obj(&obj, &work().join("tri.mtl"))?;
    }
}

proptest! {
    #![proptest_config(config(CASES_MTL))]
    /// MTL text with mutations, used by an OBJ that names its materials.
    #[test]
    fn mutated_mtl_never_panics_and_errors_name_the_files(
        edits in vec(edit(OBJ_TOKENS, OBJ_VALUES, MTL_LINES), 1..6),
        bytes in prop::option::weighted(0.2, byte_edits(3)),
    ) {
        let base = read_text(&work().join("tri.mtl"));
        let text = apply_edits(&base, &edits);
        let mtl = match bytes {
            Some(b) => apply_byte_edits(text.as_bytes(), &b, 128),
            None => text.into_bytes(),
        };
        let mtl_path = fresh("lib", "mtl");
        std::fs::write(&mtl_path, &mtl).unwrap();
        check_obj(OBJ_BASES[1].as_bytes(), &mtl_path)?;
        std::fs::remove_file(&mtl_path).unwrap();
    }
}

// ---------------------------------------------------------------------------------------------
// Images: EXR, PNG, JPEG

/// A small image with a gradient, so that compressed pixel data is not trivial.
fn small_rgb(w: u32, h: u32) -> noisefree::imaging::RgbImage {
    noisefree::imaging::RgbImage {
        width: w,
        height: h,
        pixels: (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                [x * 0.1, y * 0.2, (x * y).sin().abs()]
            })
            .collect(),
    }
}

fn small_aovs(w: u32, h: u32) -> common::Buffers {
    use noisefree::layout::{FilterVector, WelfordSums};
    let n = (w * h) as usize;
    let gb = (0..n)
        .map(|i| WelfordSums {
            depth: i as f32 * 1e-3,
            ..Default::default()
        })
        .collect();
    common::Buffers {
        spp: 4,
        variances: Some(gb),
        directions: Some(vec![[0.0, 0.0, 1.0]; n]),
        ..common::Buffers::from_fn(w, h, 100.0, |x, y| {
            let v = (y * w + x) as f32 * 0.01;
            FilterVector {
                direct: [v, 0.5, 1.0 - v],
                indirect: [0.1, v, 0.2],
                depth: 1.0 + v,
                normal: [0.0, 1.0, 0.0],
                albedo: [0.5, v, 0.25],
                albedo2: [v; 3],
            }
        })
    }
}

/// The record an AOV or samples file of a render carries: scene information and a filter's
/// settings, so that damage reaches the record's parser too.
fn small_record() -> noisefree::stats::RenderRecord {
    let mut scene = noisefree::render::SceneInfo::unknown();
    scene.path = "scenes/small.toml".into();
    scene.effects.insert("HAS_GLASS".into(), true);
    scene.scene_size = 4.5;
    let mut ddf = toml::Table::new();
    ddf.insert("kw".into(), toml::Value::Integer(7));
    ddf.insert("sky".into(), toml::Value::String("auto".into()));
    noisefree::stats::RenderRecord {
        scene: Some(scene),
        filter: Some("ddf".into()),
        settings: [("ddf".to_string(), ddf)].into(),
        extra: [("spp".to_string(), "4".to_string())].into(),
    }
}

/// Image files made by the project's own writers and the committed textures.
static IMAGES: LazyLock<Vec<(&'static str, Vec<u8>)>> = LazyLock::new(|| {
    let rgb = fresh("rgb", "exr");
    noisefree::imaging::write_exr(&rgb, &small_rgb(7, 5)).unwrap();
    let aov = fresh("aov", "exr");
    noisefree::stats::aov::write_aov_exr(&aov, &small_aovs(6, 4).frame(), &small_record()).unwrap();
    let png = fresh("img", "png");
    noisefree::imaging::write_png(&png, &small_rgb(5, 3), 0.0).unwrap();
    let mut jpeg = Vec::new();
    let rgb8 = noisefree::imaging::to_srgb8(&small_rgb(16, 9), 0.0);
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 80)
        .encode(&rgb8, 16, 9, image::ExtendedColorType::Rgb8)
        .unwrap();
    let textures = common::repo_path("scenes/textures");
    vec![
        ("exr", std::fs::read(&rgb).unwrap()),
        ("exr", std::fs::read(&aov).unwrap()),
        ("png", std::fs::read(&png).unwrap()),
        ("png", std::fs::read(textures.join("checker.png")).unwrap()),
        ("jpg", jpeg),
        ("exr", std::fs::read(textures.join("sky.exr")).unwrap()),
    ]
});

/// CRC-32 (ISO-HDLC, as PNG uses), bit by bit: the test files are small.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xffff_ffffu32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xedb8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// Recomputes the CRC of every PNG chunk whose length still fits in the file, so that a
/// mutation reaches the decoder instead of failing the checksum.
fn fix_png_crcs(b: &mut [u8]) {
    let mut at = 8;
    while at + 12 <= b.len() {
        let len = u32::from_be_bytes(b[at..at + 4].try_into().unwrap()) as usize;
        let Some(end) = (at + 8).checked_add(len).filter(|e| e + 4 <= b.len()) else {
            break;
        };
        let crc = crc32(&b[at + 4..end]);
        b[end..end + 4].copy_from_slice(&crc.to_be_bytes());
        at = end + 4;
    }
}

/// The error reading `path` as an AOV file gives (a Frame has no Debug for `unwrap_err`).
fn aov_error(path: &Path) -> anyhow::Error {
    match noisefree::stats::aov::read_aov_exr(path) {
        Ok(_) => panic!("{} was read as an AOV file", path.display()),
        Err(e) => e,
    }
}

/// The error text of an anyhow error, with its causes.
fn anyhow_text(e: &anyhow::Error) -> String {
    format!("{e:#}")
}

/// Feeds an image file to every reader that accepts it; checks no panic and named files.
fn check_image_file(bytes: &[u8], ext: &str) -> Result<(), TestCaseError> {
    let path = fresh("image", ext);
    std::fs::write(&path, bytes).unwrap();
    let shown = path.display().to_string();
    let r = no_panic("texture::load_image", || texture::load_image(&path))?;
    match &r {
        Err(e) => {
            prop_assert_eq!(&e.path, &path, "{}", e);
            prop_assert!(e.to_string().contains(&shown));
        }
        Ok((w, h, texels)) => {
            prop_assert!(*w >= 1 && *h >= 1);
            prop_assert_eq!(texels.len(), *w as usize * *h as usize);
            prop_assert!(texels.iter().flatten().all(|v| v.is_finite()));
        }
    }
    if ext == "exr" {
        let r = no_panic("read_exr_rgb", || noisefree::imaging::read_exr_rgb(&path))?;
        match &r {
            Err(e) => prop_assert!(anyhow_text(e).contains(&shown), "{}", anyhow_text(e)),
            Ok(img) => {
                prop_assert_eq!(img.pixels.len(), img.width as usize * img.height as usize)
            }
        }
        let r = no_panic("read_exr_metadata", || {
            noisefree::imaging::read_exr_metadata(&path)
        })?;
        if let Err(e) = &r {
            prop_assert!(anyhow_text(e).contains(&shown), "{}", anyhow_text(e));
        }
        let r = no_panic("read_aov_exr", || {
            noisefree::stats::aov::read_aov_exr(&path)
        })?;
        match &r {
            Err(e) => prop_assert!(anyhow_text(e).contains(&shown), "{}", anyhow_text(e)),
            Ok((frame, _)) => {
                use noisefree::layout::outputs::Output;
                let info = frame.info();
                prop_assert!(info.pixels() >= 1 && info.spp >= 1);
                prop_assert!(frame.outputs().contains(Output::Colour));
                prop_assert_eq!(frame.filter_vectors().unwrap().len(), info.pixels());
                // Every output read has every buffer, at its full size, all finite.
                for b in frame.outputs().buffers() {
                    let h = frame.host(b.id).unwrap();
                    prop_assert_eq!(
                        h.len_bytes() as u64,
                        b.bytes(
                            info.width,
                            info.height,
                            info.sample_capacity,
                            info.shadow_planes()
                        )
                    );
                    prop_assert!(h.floats().iter().all(|v| v.is_finite()), "{}", b.name);
                }
            }
        }
    }
    std::fs::remove_file(&path).unwrap();
    Ok(())
}

proptest! {
    #![proptest_config(config(CASES_EXR))]
    /// The small RGB and AOV EXRs of the project's writers, damaged.
    #[test]
    fn damaged_exr_never_panics_and_errors_name_the_file(
        which in 0usize..2,
        edits in byte_edits(5),
        window in prop::option::weighted(0.3, (any::<bool>(), (select(WINDOW_VALUES), select(WINDOW_VALUES), select(WINDOW_VALUES), select(WINDOW_VALUES)))),
    ) {
        let (ext, bytes) = &IMAGES[which];
        let mut b = bytes.clone();
        // The data window (and sometimes the display window) set to extreme corners.
        if let Some((both, (x0, y0, x1, y1))) = window {
            set_exr_window(&mut b, b"dataWindow", [x0, y0, x1, y1]);
            if both {
                set_exr_window(&mut b, b"displayWindow", [x0, y0, x1, y1]);
            }
        }
        check_image_file(&apply_byte_edits(&b, &edits, 400), ext)?;
    }
}

proptest! {
    #![proptest_config(config(CASES_SKY_EXR))]
    /// The committed sky texture (1024 x 512 half float), damaged.
    #[test]
    fn damaged_sky_exr_never_panics_and_errors_name_the_file(edits in byte_edits(4)) {
        let (ext, bytes) = &IMAGES[5];
        check_image_file(&apply_byte_edits(bytes, &edits, 400), ext)?;
    }
}

proptest! {
    #![proptest_config(config(CASES_PNG))]
    /// PNGs of the project's writer and a committed texture, damaged (mostly with their chunk
    /// checksums repaired, so that the damage reaches the decoder).
    #[test]
    fn damaged_png_never_panics_and_errors_name_the_file(
        which in 2usize..4,
        edits in byte_edits(4),
        fix_crc in proptest::bool::weighted(0.8),
    ) {
        let (ext, bytes) = &IMAGES[which];
        let mut b = apply_byte_edits(bytes, &edits, 64);
        if fix_crc {
            fix_png_crcs(&mut b);
        }
        check_image_file(&b, ext)?;
    }
}

proptest! {
    #![proptest_config(config(CASES_JPEG))]
    /// A small JPEG, damaged.
    #[test]
    fn damaged_jpeg_never_panics_and_errors_name_the_file(edits in byte_edits(4)) {
        let (ext, bytes) = &IMAGES[4];
        check_image_file(&apply_byte_edits(bytes, &edits, 200), ext)?;
    }
}

// ---------------------------------------------------------------------------------------------
// RPF sample files

static SAMPLES: LazyLock<Vec<u8>> = LazyLock::new(|| {
    use noisefree::filters::rpf::samples::SampleSet;
    let (w, h, spp) = (3u32, 2u32, 2u32);
    let samples = (0..w * h * spp)
        .map(|i| noisefree::layout::SampleVector {
            position: [(i % 3) as f32 + 0.5, (i / 6) as f32 + 0.5],
            color: [i as f32 * 0.1; 3],
            ..Default::default()
        })
        .collect();
    let p = fresh("samples", "bin");
    let mut set = SampleSet::new(w, h, spp, samples).unwrap();
    set.record = small_record();
    set.write(&p).unwrap();
    std::fs::read(&p).unwrap()
});

/// Bytes before the first sample vector of [`SAMPLES`]: the header, the record's length and
/// the record (a version-2 file).
fn samples_head() -> usize {
    32 + u32::from_le_bytes(SAMPLES[28..32].try_into().unwrap()) as usize
}

proptest! {
    #![proptest_config(config(CASES_RPF))]
    /// RPF `samples.bin` files, damaged: never a panic, errors name the file.
    #[test]
    fn damaged_rpf_samples_never_panic_and_errors_name_the_file(edits in byte_edits(4)) {
        use noisefree::filters::rpf::samples::SampleSet;
        let bytes = apply_byte_edits(&SAMPLES, &edits, samples_head());
        let path = fresh("samples", "bin");
        std::fs::write(&path, &bytes).unwrap();
        let r = no_panic("SampleSet::read", || SampleSet::read(&path))?;
        match &r {
            Err(e) => prop_assert!(
                anyhow_text(e).contains(&path.display().to_string()),
                "{}",
                anyhow_text(e)
            ),
            Ok(set) => {
                prop_assert!(set.validate().is_ok());
                prop_assert!(set.clone().into_frame().is_ok());
            }
        }
        std::fs::remove_file(&path).unwrap();
    }
}

// ---------------------------------------------------------------------------------------------
// Hand-picked cases

fn expect_scene_error(path: &Path, text: &str) -> SceneError {
    let r = load_scene_str(path, text);
    check_scene(path, Some(text), &r).unwrap();
    r.err()
        .unwrap_or_else(|| panic!("expected an error for:\n{text}"))
}

/// The mutation bases are valid scenes: the mutations start from something that loads.
#[test]
fn every_base_scene_and_mesh_loads() {
    for (name, text) in SCENES.iter() {
        let path = work().join(format!("{name}.toml"));
        let s = load_scene_str(&path, text).unwrap_or_else(|e| panic!("{name}: {e}"));
        check_scene_invariants(&s).unwrap();
    }
    let mtl = work().join("tri.mtl");
    for (i, obj) in OBJ_BASES.iter().enumerate() {
        let opener = |_: &Path| {
            let f = std::fs::File::open(&mtl).unwrap();
            Ok((mtl.clone(), std::io::BufReader::new(f)))
        };
        let parts = mesh::load_obj_bytes(Path::new("base.obj"), obj.as_bytes(), &opener)
            .unwrap_or_else(|e| panic!("OBJ base {i}: {e}"));
        check_parts(&parts).unwrap();
        assert!(parts.iter().map(|p| p.triangle_count()).sum::<usize>() > 0);
    }
}

#[test]
fn the_fixture_scene_loads_with_everything_it_names() {
    let s = load_scene_str(
        &fixture("minimal.toml"),
        &read_text(&fixture("minimal.toml")),
    )
    .unwrap();
    check_scene_invariants(&s).unwrap();
    check_filter_tables(&fixture("minimal.toml"), &s).unwrap();
    assert_eq!(s.filter.method.as_deref(), Some("ddf"));
    assert!(s.filter.settings.contains_key("ddf"), "{:?}", s.filter);
    // quad: 2 triangles; tri.obj: a quad (2) and two triangles.
    assert_eq!(s.triangles.len(), 6);
    // checker and the MTL's map_Kd.
    assert_eq!(s.textures.len(), 2);
    assert!(s.environment.is_some());
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    let kinds: Vec<_> = s
        .materials
        .iter()
        .map(|m| format!("{:?}", m.kind))
        .collect();
    assert!(kinds.iter().any(|k| k.starts_with("Metal")), "{kinds:?}");
}

#[test]
fn filter_settings_written_flat_or_for_unknown_filters_are_explained() {
    use noisefree::filters::{FilterRequest, Registry};
    let path = work().join("filters.toml");
    let camera = "[camera]\norigin = [0, 0, 5]\ntarget = [0, 0, 0]\n\n";
    // The format before filters had their own tables: the loader says where settings go.
    let e = expect_scene_error(
        &path,
        &format!("{camera}[filter]\nmethod = \"ddf\"\nkw = 7\n"),
    );
    assert_eq!(e.position.map(|p| p.0), Some(5), "{e}");
    assert!(e.message.contains("[filter.ddf] kw"), "{e}");
    // Tables the loader keeps and the registry refuses, at the table's line.
    for (table, needle) in [
        ("[filter.nope]\nkw = 7\n", "no filter of that name"),
        ("[filter.atrous]\niterations = 99\n", "iterations"),
        ("[filter.ddf]\nkww = 7\n", "kww"),
        ("[filter.rpf]\nsigma2_8 = -1\n", "sigma2_8"),
    ] {
        let s = load_scene_str(&path, &format!("{camera}{table}")).unwrap();
        check_filter_tables(&path, &s).unwrap();
        let request = FilterRequest {
            scene: s.filter.settings.clone(),
            scene_origin: path.display().to_string(),
            scene_lines: s.filter.lines.clone(),
            ..Default::default()
        };
        let e = Registry::builtin()
            .configure_all(&request, &noisefree::render::SceneInfo::unknown())
            .unwrap_err();
        let t = anyhow_text(&e);
        assert!(
            t.contains("filters.toml:5: [filter.") && t.contains(needle),
            "{t}"
        );
    }
}

#[test]
fn empty_and_blank_scene_files_name_the_missing_camera() {
    for text in ["", "\n\n", "# only a comment\n", "\u{feff}"] {
        let path = work().join("empty.toml");
        std::fs::write(&path, text).unwrap();
        let e = load_scene(&path).unwrap_err();
        assert_eq!(e.path, path);
        assert!(e.message.contains("camera"), "{e}");
    }
}

#[test]
fn a_utf8_bom_and_windows_line_endings_are_read() {
    let text = read_text(&fixture("minimal.toml"));
    let path = fixture("minimal.toml");
    let plain = load_scene_str(&path, &text).unwrap();
    let bom = load_scene_str(&path, &format!("\u{feff}{text}"));
    let crlf = load_scene_str(&path, &text.replace('\n', "\r\n"));
    for r in [bom, crlf] {
        let s = r.unwrap();
        assert_eq!(s.triangles, plain.triangles);
        assert_eq!(s.render, plain.render);
        assert_eq!(s.camera, plain.camera);
    }
    // Positions count lines the same way with CRLF.
    let bad = text
        .replace("radius = 0.5", "radius = -0.5")
        .replace('\n', "\r\n");
    let e = expect_scene_error(&path, &bad);
    let line = text.lines().position(|l| l == "radius = 0.5").unwrap() + 1;
    assert_eq!(e.position, Some((line, 10)), "{e}");
    // And with a BOM, which is not a column of its own.
    let e = expect_scene_error(
        &path,
        &format!("\u{feff}{}", text.replace("radius = 0.5", "radius = -0.5")),
    );
    assert_eq!(e.position, Some((line, 10)), "{e}");
}

#[test]
fn an_obj_with_windows_line_endings_and_a_bom_loads() {
    let text = read_text(&fixture("tri.obj"));
    let mtl = work().join("tri.mtl");
    let opener = |_: &Path| {
        Ok((
            mtl.clone(),
            std::io::BufReader::new(std::fs::File::open(&mtl).unwrap()),
        ))
    };
    let plain = mesh::load_obj_bytes(Path::new("tri.obj"), text.as_bytes(), &opener).unwrap();
    let crlf = text.replace('\n', "\r\n");
    let parts = mesh::load_obj_bytes(Path::new("tri.obj"), crlf.as_bytes(), &opener).unwrap();
    assert_eq!(parts, plain);
    let bom = format!("\u{feff}{text}");
    let parts = mesh::load_obj_bytes(Path::new("tri.obj"), bom.as_bytes(), &opener).unwrap();
    assert_eq!(parts, plain);
}

#[test]
fn directories_are_refused_by_every_loader() {
    let dir = work().join("a_directory.toml");
    std::fs::create_dir_all(&dir).unwrap();
    let e = load_scene(&dir).unwrap_err();
    assert!(e.to_string().contains("is a directory"), "{e}");
    let e = mesh::load_obj(&dir).unwrap_err();
    assert!(e.to_string().contains("is a directory"), "{e}");
    assert_eq!(e.path, dir);
    for ext in ["png", "exr"] {
        let d = work().join(format!("dir.{ext}"));
        std::fs::create_dir_all(&d).unwrap();
        let e = texture::load_image(&d).unwrap_err();
        assert!(e.to_string().contains("is a directory"), "{e}");
        assert_eq!(e.path, d);
    }
    let d = work().join("dir.exr");
    for e in [
        noisefree::imaging::read_exr_rgb(&d).unwrap_err(),
        aov_error(&d),
    ] {
        let t = anyhow_text(&e);
        assert!(
            t.contains(&d.display().to_string()) && t.contains("directory"),
            "{t}"
        );
    }
    // Through a scene: the directory named as a mesh, a texture and an MTL map_Kd.
    let scene = work().join("dirs.toml");
    for (table, line) in [
        ("[[mesh]]\nfile = \"models\"\n", 6),
        ("[[texture]]\nname = \"t\"\nfile = \"textures\"\n", 7),
    ] {
        let text = format!("[camera]\norigin = [0, 0, 5]\ntarget = [0, 0, 0]\n\n{table}");
        let e = expect_scene_error(&scene, &text);
        assert_eq!(e.position.map(|p| p.0), Some(line), "{e}");
        assert!(e.message.contains("is a directory"), "{e}");
    }
}

#[test]
fn unreadable_files_are_reported_with_their_name() {
    use std::os::unix::fs::PermissionsExt;
    let path = work().join("locked.toml");
    std::fs::write(&path, SMALL_SCENES[0].1).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o000)).unwrap();
    if std::fs::read(&path).is_ok() {
        // Running as root: permissions do not stop reads, so there is nothing to test here.
        eprintln!("skipped: this user can read a file with mode 000 (root)");
        return;
    }
    let e = load_scene(&path).unwrap_err();
    assert!(e.to_string().contains("locked.toml"), "{e}");
    assert!(
        e.message.contains("cannot read") || e.message.contains("cannot open"),
        "{e}"
    );
    let obj = work().join("locked.obj");
    std::fs::write(&obj, "v 0 0 0\n").unwrap();
    std::fs::set_permissions(&obj, std::fs::Permissions::from_mode(0o000)).unwrap();
    let e = mesh::load_obj(&obj).unwrap_err();
    assert_eq!(e.path, obj);
    let png = work().join("locked.png");
    std::fs::write(&png, &IMAGES[2].1).unwrap();
    std::fs::set_permissions(&png, std::fs::Permissions::from_mode(0o000)).unwrap();
    let e = texture::load_image(&png).unwrap_err();
    assert_eq!(e.path, png);
    let exr = work().join("locked.exr");
    std::fs::write(&exr, &IMAGES[0].1).unwrap();
    std::fs::set_permissions(&exr, std::fs::Permissions::from_mode(0o000)).unwrap();
    assert!(
        anyhow_text(&noisefree::imaging::read_exr_rgb(&exr).unwrap_err()).contains("locked.exr")
    );
}

#[test]
fn empty_files_are_clear_errors() {
    let png = work().join("empty.png");
    std::fs::write(&png, b"").unwrap();
    let e = texture::load_image(&png).unwrap_err();
    assert_eq!(e.path, png);
    let exr = work().join("empty.exr");
    std::fs::write(&exr, b"").unwrap();
    let e = texture::load_image(&exr).unwrap_err();
    assert_eq!(e.path, exr);
    for e in [
        noisefree::imaging::read_exr_rgb(&exr).unwrap_err(),
        aov_error(&exr),
    ] {
        assert!(anyhow_text(&e).contains("empty.exr"), "{}", anyhow_text(&e));
    }
    // An empty OBJ has no triangles: it loads, and a scene with it has none.
    let obj = work().join("empty.obj");
    std::fs::write(&obj, b"").unwrap();
    let parts = mesh::load_obj(&obj).unwrap();
    assert!(parts.iter().all(|p| p.indices.is_empty()));
}

#[test]
fn a_zero_sized_image_is_an_error() {
    // 0 x 0 EXR: the writer refuses it or the reader does; either way no panic and the file named.
    let exr = work().join("zero.exr");
    let img = noisefree::imaging::RgbImage {
        width: 0,
        height: 0,
        pixels: Vec::new(),
    };
    if noisefree::imaging::write_exr(&exr, &img).is_ok() {
        let e = texture::load_image(&exr).unwrap_err();
        assert_eq!(e.path, exr);
        assert!(noisefree::imaging::read_exr_rgb(&exr).is_err());
    }
    // A PNG header that says 0 x 0 (the IHDR chunk of a real PNG with its sizes zeroed).
    let mut png = IMAGES[2].1.clone();
    png[16..24].fill(0);
    let p = work().join("zero.png");
    std::fs::write(&p, &png).unwrap();
    let e = texture::load_image(&p).unwrap_err();
    assert_eq!(e.path, p);
}

#[test]
fn degenerate_triangles_are_skipped_with_one_warning() {
    let scene = work().join("degenerate.toml");
    std::fs::copy(fixture("degenerate.obj"), work().join("degenerate.obj")).unwrap();
    let text = "[camera]\norigin = [0, 0, 5]\ntarget = [0, 0, 0]\n\n[[material]]\nname = \"w\"\n\
                type = \"diffuse\"\n\n[[mesh]]\nfile = \"degenerate.obj\"\nmaterial = \"w\"\n";
    let s = load_scene_str(&scene, text).unwrap();
    check_scene_invariants(&s).unwrap();
    assert_eq!(s.triangles.len(), 1, "only the good triangle stays");
    assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
    assert!(
        s.warnings[0].contains("degenerate.obj") && s.warnings[0].contains("skipped 6"),
        "{:?}",
        s.warnings
    );
}

#[test]
fn a_face_past_the_vertex_list_names_its_line() {
    let path = fixture("face_past_end.obj");
    let e = mesh::load_obj(&path).unwrap_err();
    assert_eq!(e.path, path);
    assert_eq!(e.position.map(|p| p.0), Some(7), "{e}");
    // Normals and texture coordinates past their lists too.
    for (text, line) in [
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//2\n", 5),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\nf 1/3 2/1 3/1\n",
            6,
        ),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", 4),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", 4),
        // An index whose byte offset would overflow (3 x index) must not wrap to a valid one.
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0 0 1\nf 1//6148914691236517207 2//1 3//1\n",
            6,
        ),
    ] {
        let p = Path::new("bad.obj");
        let e = mesh::load_obj_bytes(p, text.as_bytes(), &|_: &Path| unreachable!()).unwrap_err();
        assert_eq!(e.position.map(|p| p.0), Some(line), "{text}: {e}");
    }
}

#[test]
fn a_missing_or_broken_mtl_names_both_files() {
    let obj = work().join("needs_missing.obj");
    std::fs::write(
        &obj,
        "mtllib nowhere.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let e = mesh::load_obj(&obj).unwrap_err();
    let t = e.to_string();
    assert!(
        t.contains("nowhere.mtl") && t.contains("needs_missing.obj"),
        "{t}"
    );
    // A Kd with two numbers: tobj 4.0.5 panics on it (parse_float3 unwraps a 3-array).
    let mtl = work().join("short_kd.mtl");
    std::fs::write(&mtl, "newmtl a\nKd 1 1\n").unwrap();
    let obj = work().join("short_kd.obj");
    std::fs::write(
        &obj,
        "mtllib short_kd.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n",
    )
    .unwrap();
    let e = no_panic("load_obj", || mesh::load_obj(&obj))
        .unwrap()
        .unwrap_err();
    let t = e.to_string();
    assert!(
        t.contains("short_kd.mtl") && t.contains("short_kd.obj"),
        "{t}"
    );
    assert_eq!(e.position.map(|p| p.0), Some(2), "{t}");
}

#[test]
fn a_broken_map_kd_names_the_scene_line_the_mtl_and_the_image() {
    let dir = work().join("mapkd");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("m.mtl"), "newmtl a\nKd 1 1 1\nmap_Kd broken.png\n").unwrap();
    std::fs::write(dir.join("broken.png"), b"not a png").unwrap();
    std::fs::write(
        dir.join("m.obj"),
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n",
    )
    .unwrap();
    let scene = dir.join("s.toml");
    let text = "[camera]\norigin = [0, 0, 5]\ntarget = [0, 0, 0]\n\n[[mesh]]\nfile = \"m.obj\"\n";
    let e = expect_scene_error(&scene, text);
    assert_eq!(e.position, Some((6, 8)), "{e}");
    let t = e.to_string();
    assert!(
        t.contains("s.toml") && t.contains("broken.png") && t.contains("\"a\""),
        "{t}"
    );
}

#[test]
fn exr_with_non_finite_pixels_is_refused_as_a_texture() {
    let exr = work().join("nan.exr");
    let mut img = small_rgb(3, 3);
    img.pixels[4] = [f32::NAN, 0.0, 0.0];
    noisefree::imaging::write_exr(&exr, &img).unwrap();
    let e = texture::load_image(&exr).unwrap_err();
    assert!(e.message.contains("(1, 1)"), "{e}");
}

#[test]
fn aov_files_with_missing_channels_or_bad_spp_are_explained() {
    // An RGB EXR is not an AOV file: the missing channel is named.
    let exr = work().join("plain_rgb.exr");
    std::fs::write(&exr, &IMAGES[0].1).unwrap();
    let t = anyhow_text(&aov_error(&exr));
    assert!(
        t.contains("plain_rgb.exr") && t.contains("channel") && t.contains("direct.R"),
        "{t}"
    );
    // spp 0.
    let mut b = small_aovs(2, 2);
    b.spp = 0;
    let aov = work().join("spp0.exr");
    noisefree::stats::aov::write_aov_exr(&aov, &b.frame(), &Default::default()).unwrap();
    let t = anyhow_text(&aov_error(&aov));
    assert!(t.contains("spp0.exr") && t.contains("spp"), "{t}");
}

#[test]
fn wrong_types_huge_numbers_and_unicode_point_at_the_value() {
    let path = work().join("values.toml");
    let base = SMALL_SCENES[0].1;
    for (from, to, line, needle) in [
        ("radius = 1", "radius = \"one\"", Some(11), "expected"),
        ("radius = 1", "radius = nan", Some(11), "radius"),
        ("radius = 1", "radius = 1e999", Some(11), ""),
        (
            "origin = [0, 0, 5]",
            "origin = [0, 0, 1e39]",
            None,
            "finite",
        ),
        (
            "[[sphere]]",
            "[[sphere]]\nwidth = 3",
            Some(10),
            "unknown field",
        ),
        (
            "name = \"w\"",
            "name = \"w\u{202e}é𝔘\"",
            Some(12),
            "unknown material",
        ),
        (
            "[camera]",
            "[render]\nwidth = 9223372036854775808\n[camera]",
            Some(2),
            "",
        ),
        (
            "[camera]",
            "[render]\nspp = 4294967296\n[camera]",
            Some(2),
            "spp",
        ),
    ] {
        let text = base.replace(from, to);
        assert_ne!(text, base);
        let e = expect_scene_error(&path, &text);
        if line.is_some() {
            assert_eq!(e.position.map(|p| p.0), line, "{text}\n{e}");
        }
        assert!(e.message.contains(needle), "{e}");
    }
}

/// Corner coordinates for EXR windows: ordinary, at the limits of the format, past them.
const WINDOW_VALUES: &[i32] = &[
    -1,
    0,
    1,
    4,
    6,
    7,
    1 << 16,
    1 << 20,
    1 << 29,
    (1 << 30) - 2,
    -(1 << 30) + 2,
    i32::MAX,
    i32::MIN,
];

/// Overwrites an EXR header's box2i attribute `name` (dataWindow, displayWindow) with
/// [x_min, y_min, x_max, y_max].
fn set_exr_window(bytes: &mut [u8], name: &[u8], corners: [i32; 4]) {
    let key = [name, b"\0box2i\0"].concat();
    let at = bytes
        .windows(key.len())
        .position(|w| w == key)
        .expect("an EXR header with the window attribute")
        + key.len()
        + 4;
    for (k, c) in corners.iter().enumerate() {
        bytes[at + 4 * k..at + 4 * k + 4].copy_from_slice(&c.to_le_bytes());
    }
}

/// Sets the max corner of both windows, keeping the min corner at 0.
fn set_exr_windows(bytes: &mut [u8], x_max: i32, y_max: i32) {
    for name in [&b"dataWindow"[..], &b"displayWindow"[..]] {
        set_exr_window(bytes, name, [0, 0, x_max, y_max]);
    }
}

/// Found by the EXR property: a header whose data window claims 10^9 x 512 pixels made the exr
/// crate's reader allocate 8 TB for the image before reading any pixel, which aborts the
/// process (an allocation failure is not a panic). The readers now check the header first.
#[test]
fn exr_headers_claiming_huge_images_are_refused_before_allocating() {
    for (which, x_max, y_max) in [
        (0usize, 1_000_000_000, 4),
        (0, 1 << 20, 1 << 20),
        (1, 1 << 29, 3),
        (5, 1_000_000_000, 511),
        (5, 1 << 29, 1 << 29),
    ] {
        let mut b = IMAGES[which].1.clone();
        set_exr_windows(&mut b, x_max, y_max);
        let path = work().join(format!("huge-{which}-{x_max}.exr"));
        std::fs::write(&path, &b).unwrap();
        let shown = path.display().to_string();
        // Terabytes: more than any machine has, so the header check must be what refuses them.
        let terabytes = (x_max as u64 + 1) * (y_max as u64 + 1) * 12 > 1 << 40;
        let e = texture::load_image(&path).unwrap_err();
        assert_eq!(e.path, path);
        assert!(!terabytes || e.message.contains("would take"), "{e}");
        for e in [
            noisefree::imaging::read_exr_rgb(&path).unwrap_err(),
            aov_error(&path),
        ] {
            let t = anyhow_text(&e);
            assert!(t.contains(&shown), "{t}");
            assert!(!terabytes || t.contains("would take"), "{t}");
        }
    }
}

/// Found by the scene property: a sphere light with emission [0, 0, 0] was accepted as a light
/// that emits nothing (an emitter material with zero emission was already refused).
#[test]
fn a_sphere_light_that_emits_nothing_is_an_error_at_its_emission() {
    let path = work().join("dark_light.toml");
    let text = format!(
        "{}\n[[light]]\ntype = \"sphere\"\ncenter = [0, 3, 0]\nradius = 1\nemission = [0, 0, 0]\n",
        SMALL_SCENES[0].1
    );
    let e = expect_scene_error(&path, &text);
    assert_eq!(e.position, Some((18, 12)), "{e}");
    assert!(e.message.contains("positive emission"), "{e}");
}

/// Devices are not files: `/dev/zero` as a scene, mesh, texture or MTL would be read until
/// memory runs out. They are refused before reading.
#[cfg(unix)]
#[test]
fn devices_are_refused_before_reading() {
    let zero = Path::new("/dev/zero");
    if !zero.exists() {
        return;
    }
    let e = load_scene(zero).unwrap_err();
    assert!(e.message.contains("not a regular file"), "{e}");
    let e = mesh::load_obj(zero).unwrap_err();
    assert!(e.message.contains("not a regular file"), "{e}");
    let e = texture::load_image(zero).unwrap_err();
    assert!(e.message.contains("not a regular file"), "{e}");
    let obj = work().join("zero_mtl.obj");
    std::fs::write(
        &obj,
        "mtllib /dev/zero\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let e = mesh::load_obj(&obj).unwrap_err();
    assert!(
        e.to_string().contains("not a regular file") && e.to_string().contains("zero_mtl.obj"),
        "{e}"
    );
    let path = work().join("zero.toml");
    for table in [
        "[[mesh]]\nfile = \"/dev/zero\"\n",
        "[[texture]]\nname = \"t\"\nfile = \"/dev/zero\"\n",
    ] {
        let text = format!("{}{table}", SMALL_SCENES[0].1);
        let e = expect_scene_error(&path, &text);
        assert!(e.message.contains("not a regular file"), "{e}");
        assert!(e.position.is_some_and(|p| p.0 >= 14), "{e}");
    }
}

/// The default `up` has no place in the text: an error about it points at the camera.
#[test]
fn a_view_along_the_default_up_points_at_the_camera() {
    let path = work().join("up.toml");
    let text = SMALL_SCENES[0]
        .1
        .replace("origin = [0, 0, 5]", "origin = [0, 5, 0]");
    let e = expect_scene_error(&path, &text);
    assert!(e.message.contains("parallel"), "{e}");
    assert!(e.position.is_some_and(|p| p.0 <= 3), "{e}");
}
