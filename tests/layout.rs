//! One source of truth for what the host shares with the kernels: the committed
//! kernels/layout.cl and kernels/render/outputs.cl are what src/layout generates; the device lays
//! every struct out exactly as Rust does; the render kernel's arguments are the ones the host
//! binds, by name and in order.

mod common;

use noisefree::layout::cl::{all_declarations, generated_layout_cl, generated_outputs_cl};
use noisefree::layout::outputs::BUFFERS;

fn check_generated(rel: &str, generated: &str) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(rel);
    if std::env::var_os("NOISEFREE_BLESS").is_some() {
        std::fs::write(&path, generated).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap();
    assert!(
        committed == generated,
        "{rel} is stale: run `NOISEFREE_BLESS=1 cargo test --test layout` and commit it"
    );
}

#[test]
fn committed_kernel_headers_are_generated_from_src_layout() {
    check_generated("kernels/layout.cl", &generated_layout_cl());
    check_generated("kernels/render/outputs.cl", &generated_outputs_cl());
}

#[test]
fn device_sizes_and_offsets_match_rust() {
    let gpu = common::gpu();
    // One pointer argument per struct; the whole probe kernel is generated here.
    let decls = all_declarations();
    let mut params = String::from("__global uint* out");
    let mut body = String::new();
    let mut expected: Vec<(String, usize)> = Vec::new();
    let mut push = |body: &mut String, what: String, code: String, want: usize| {
        body.push_str(&format!("out[k++] = (uint)({code}); "));
        expected.push((what, want));
    };
    for (i, d) in decls.iter().enumerate() {
        params.push_str(&format!(", __global {}* p{i}", d.name));
        push(
            &mut body,
            format!("sizeof({})", d.name),
            format!("sizeof(*p{i})"),
            d.size,
        );
        for f in &d.fields {
            push(
                &mut body,
                format!("offsetof({}, {})", d.name, f.name),
                format!("(__global char*)&(p{i}->{}) - (__global char*)p{i}", f.name),
                f.offset,
            );
        }
    }
    // Every output buffer's element is a layout struct (or a vector type) of the same size.
    for b in BUFFERS {
        push(
            &mut body,
            format!("sizeof({}) for buffer {}", b.element, b.name),
            format!("sizeof({})", b.element),
            b.element_bytes,
        );
    }
    let prelude = format!(
        "#define LAYOUT_PROBE_KERNEL __kernel void probe_layout({params}) {{ \
         if (get_global_id(0) != 0) return; uint k = 0; {body} }}\n"
    );
    let program = gpu
        .program(
            "test/probes.cl",
            &noisefree::render::features::generic_defines(),
            &prelude,
        )
        .unwrap();
    let out = gpu.zeroed::<u32>(expected.len(), "probe output").unwrap();
    let dummy = gpu.zeroed::<u8>(4096, "probe structs").unwrap();
    let mut kb = ocl::Kernel::builder();
    kb.program(&program)
        .name("probe_layout")
        .queue(gpu.queue.clone())
        .global_work_size(1)
        .arg(&out);
    for _ in &decls {
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
        std::mem::size_of::<noisefree::layout::FilterVector>(),
        64,
        "F is exactly one float16 (§6.2.1)"
    );
}

#[test]
fn render_kernel_arguments_are_bound_by_name_in_order() {
    // The host binds every argument of `render` by name (src/render/mod.rs); the kernel's own
    // argument names, from the OpenCL compiler, must be the same list in the same order.
    let gpu = common::gpu();
    let mut defines = noisefree::render::features::generic_defines();
    defines.push(("DEBUG_COUNTERS".into(), "0".into()));
    let program = gpu
        .program_with_options("render/pathtrace.cl", &defines, "", "-cl-kernel-arg-info")
        .unwrap();
    let kernel = ocl::core::create_kernel(&program, "render").unwrap();
    let host = noisefree::render::Renderer::argument_names();
    let n = match ocl::core::get_kernel_info(&kernel, ocl::core::KernelInfo::NumArgs).unwrap() {
        ocl::core::KernelInfoResult::NumArgs(n) => n as usize,
        other => panic!("{other:?}"),
    };
    let mut device = Vec::new();
    for i in 0..n {
        match ocl::core::get_kernel_arg_info(
            &kernel,
            i as u32,
            ocl::core::KernelArgInfo::Name,
            None,
        ) {
            Ok(ocl::core::KernelArgInfoResult::Name(name)) => device.push(name),
            other => panic!("argument {i}: {other:?}"),
        }
    }
    assert_eq!(device, host);
}
