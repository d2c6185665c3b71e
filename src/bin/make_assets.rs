//! Writes the bundled procedural textures: `cargo run --release --bin make_assets -- DIR`
//! (the repository keeps them in scenes/textures).

use std::path::PathBuf;

fn main() -> anyhow::Result<()> {
    let dir = std::env::args_os()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("scenes/textures"));
    for path in noisefree::scene::assets::textures::write_all(&dir)? {
        let size = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
        println!("{} ({} KiB)", path.display(), size.div_ceil(1024));
    }
    Ok(())
}
