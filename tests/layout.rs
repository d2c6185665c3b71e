//! One source of truth for shared structs: the committed kernels/layout.cl is what
//! src/layout.rs generates, and the device lays every struct out exactly as Rust does.

mod common;

use noisefree::layout::{DeviceStruct, all_declarations, generated_cl_header};

#[test]
fn committed_header_is_generated_from_src_layout() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/kernels/layout.cl");
    let generated = generated_cl_header();
    if std::env::var_os("NOISEFREE_BLESS").is_some() {
        std::fs::write(path, &generated).unwrap();
    }
    let committed = std::fs::read_to_string(path).unwrap();
    assert!(
        committed == generated,
        "kernels/layout.cl is stale: run `NOISEFREE_BLESS=1 cargo test --test layout` and commit it"
    );
}

#[test]
fn device_sizes_and_offsets_match_rust() {
    let gpu = common::gpu();
    // One pointer argument per struct, in all_declarations() order (see kernels/test/probes.cl).
    let letters = [
        "a", "b", "c", "d", "e", "f", "g", "h", "i", "j", "k2", "l", "m", "n",
    ];
    let decls = all_declarations();
    assert_eq!(decls.len(), letters.len());
    let mut body = String::new();
    let mut expected: Vec<(String, usize)> = Vec::new();
    for ((name, _, fields, size), p) in decls.iter().zip(letters) {
        body.push_str(&format!("SIZE({p}) "));
        expected.push((format!("sizeof({name})"), *size));
        for f in fields {
            body.push_str(&format!("OFFSET({p}, {}) ", f.name));
            expected.push((format!("offsetof({name}, {})", f.name), f.offset));
        }
    }
    let prelude = format!("#define LAYOUT_PROBE_BODY {body}\n");
    let program = gpu
        .program("test/probes.cl", &common::generic_defines(), &prelude)
        .unwrap();
    let out = gpu.zeroed::<u32>(expected.len(), "probe output").unwrap();
    let dummy = gpu.zeroed::<u8>(4096, "probe structs").unwrap();
    let mut kb = ocl::Kernel::builder();
    kb.program(&program)
        .name("probe_layout")
        .queue(gpu.queue.clone())
        .global_work_size(1)
        .arg(&out);
    for _ in 0..letters.len() {
        kb.arg(&dummy);
    }
    let kernel = kb.build().unwrap();
    unsafe { kernel.enq().unwrap() };
    let mut got = vec![0u32; expected.len()];
    out.read(&mut got).enq().unwrap();
    for ((what, want), got) in expected.iter().zip(&got) {
        assert_eq!(*got as usize, *want, "{what}: device {got}, Rust {want}");
    }
    assert_eq!(
        noisefree::layout::FilterVector::size(),
        64,
        "F is exactly one float16 (§6.2.1)"
    );
}
