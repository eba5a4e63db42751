//! Every shader module the viewer compiles, validated by naga without a GPU, and every Rust
//! struct and constant shared with WGSL checked against the shader's own layout.

use super::REGISTRY;
use super::projection::{self, EMPTY, FrameUniforms, GROUP_SIZE, GpuRange, PIXEL_GROUP};
use super::shader::ShaderSource;
use naga::valid::{Capabilities, ValidationFlags, Validator};

/// The eight screen sectors' directions, counter-clockwise from +x (y up), as the shaders that
/// split a pixel's neighbourhood into sectors number them.
pub const SECTOR_DIRECTIONS: [(i32, i32); 8] = [
    (1, 0),
    (1, 1),
    (0, 1),
    (-1, 1),
    (-1, 0),
    (-1, -1),
    (0, -1),
    (1, -1),
];

/// Every module, composed as the pipelines compose them, for a device with and without
/// 64-bit atomics.
fn all_shaders(int64: bool) -> Vec<ShaderSource> {
    let mut all = projection::shaders(int64);
    for p in REGISTRY {
        all.extend((p.shaders)(int64));
    }
    all
}

pub(crate) fn parse(s: &ShaderSource) -> naga::Module {
    match naga::front::wgsl::parse_str(&s.compose()) {
        Ok(m) => m,
        Err(e) => panic!("{}: {}", s.label, e.emit_to_string(&s.compose())),
    }
}

/// Validates `module` and gives its `override` constants the source's values, as the pipeline
/// does: a value for a constant the module does not declare fails.
fn validate(s: &ShaderSource, module: &naga::Module, caps: Capabilities) {
    let mut v = Validator::new(ValidationFlags::all(), caps);
    let info = match v.validate(module) {
        Ok(info) => info,
        Err(e) => panic!("{}: {}", s.label, e.emit_to_string(&s.compose())),
    };
    let mut constants = naga::back::PipelineConstants::default();
    for (name, value) in &s.constants {
        constants.insert(name.to_string(), *value);
    }
    let entry = Some((naga::ShaderStage::Compute, s.entry));
    if let Err(e) =
        naga::back::pipeline_constants::process_overrides(module, &info, entry, &constants)
    {
        panic!("{}: the constants {:?}: {e}", s.label, s.constants);
    }
}

/// Parses and validates `s` as a device with the capabilities `caps` gets it.
pub(crate) fn parse_and_validate_with(s: &ShaderSource, caps: Capabilities) {
    validate(s, &parse(s), caps);
}

/// Parses and validates `s` as a device with 64-bit atomic min/max gets it (the pipelines'
/// 64-bit paths need no more: Metal has no other 64-bit atomics).
pub(crate) fn parse_and_validate(s: &ShaderSource) {
    let caps = Capabilities::default()
        | Capabilities::SHADER_INT64
        | Capabilities::SHADER_INT64_ATOMIC_MIN_MAX;
    validate(s, &parse(s), caps);
}

#[test]
fn every_shader_module_parses_and_validates() {
    let int64_caps = Capabilities::SHADER_INT64 | Capabilities::SHADER_INT64_ATOMIC_MIN_MAX;
    for int64 in [false, true] {
        let caps = if int64 {
            Capabilities::default() | int64_caps
        } else {
            Capabilities::default()
        };
        let shaders = all_shaders(int64);
        // Each pipeline compiles at least its own shading beside the projection's modules.
        let least = projection::shaders(int64).len() + REGISTRY.len();
        assert!(shaders.len() > least, "{} modules", shaders.len());
        for s in &shaders {
            let module = parse(s);
            validate(s, &module, caps);
            assert!(
                module.entry_points.iter().any(|e| e.name == s.entry),
                "{}: no entry point {}",
                s.label,
                s.entry
            );
        }
    }
}

#[test]
fn the_32_bit_path_needs_no_64_bit_capability() {
    // The GL backend (llvmpipe) has no 64-bit atomics: its modules must validate without.
    for s in &all_shaders(false) {
        let module = parse(s);
        validate(s, &module, Capabilities::default());
    }
}

/// The size and the member offsets of the WGSL struct `name`.
pub(crate) fn wgsl_layout(module: &naga::Module, name: &str) -> (u32, Vec<(String, u32)>) {
    let ty = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no struct {name} in the shader"));
    match &ty.1.inner {
        naga::TypeInner::Struct { members, span } => (
            *span,
            members
                .iter()
                .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
                .collect(),
        ),
        other => panic!("{name} is not a struct: {other:?}"),
    }
}

/// The size and the field offsets of a Rust struct, named as the WGSL members are.
macro_rules! rust_layout {
    ($t:ty { $($field:ident),* $(,)? }) => {
        (
            std::mem::size_of::<$t>() as u32,
            vec![$((stringify!($field).to_string(), std::mem::offset_of!($t, $field) as u32)),*],
        )
    };
}
pub(crate) use rust_layout;

/// The most storage buffers one of `shaders` binds: what a pipeline checks the adapter for
/// before compiling (`GpuContext::require_storage_buffers`).
pub(crate) fn most_storage_buffers(shaders: &[ShaderSource]) -> Option<u32> {
    shaders
        .iter()
        .map(|s| {
            parse(s)
                .global_variables
                .iter()
                .filter(|(_, g)| matches!(g.space, naga::AddressSpace::Storage { .. }))
                .count() as u32
        })
        .max()
}

/// The module `label` as a pipeline composes it (with 64-bit atomics).
pub(crate) fn module_named(label: &str) -> naga::Module {
    let s = all_shaders(true)
        .into_iter()
        .find(|s| s.label == label)
        .unwrap_or_else(|| panic!("no module {label}"));
    parse(&s)
}

#[test]
fn rust_structs_match_their_wgsl_layouts() {
    let project = module_named("project int64");
    assert_eq!(
        wgsl_layout(&project, "Frame"),
        rust_layout!(FrameUniforms {
            view_proj,
            width,
            height,
            point_size,
            size_mode,
            focal_px,
            colour_mode,
            z_min,
            z_max,
            arena_shift,
            background,
            clip_count,
            footprint,
            shading,
            arena_slots,
            intensity_scale,
            filters,
            return_lo,
            return_hi,
            ranges,
            class_mask,
            clip_boxes,
            eye,
            normals_turned,
            near,
            far,
        }),
        "FrameUniforms against Frame (frame.wgsl)"
    );
    assert_eq!(
        wgsl_layout(&project, "Range"),
        rust_layout!(GpuRange {
            start,
            count,
            first_group,
            spacing,
            centre,
            children
        }),
        "GpuRange against Range (frame.wgsl)"
    );
}

/// The value of the WGSL constant `name`.
pub(crate) fn wgsl_const(module: &naga::Module, name: &str) -> u64 {
    let (_, c) = module
        .constants
        .iter()
        .find(|(_, c)| c.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no constant {name}"));
    match module.global_expressions[c.init] {
        naga::Expression::Literal(naga::Literal::U32(v)) => v as u64,
        naga::Expression::Literal(naga::Literal::I32(v)) => v as u64,
        naga::Expression::Literal(naga::Literal::AbstractInt(v)) => v as u64,
        ref other => panic!("{name} is not an integer literal: {other:?}"),
    }
}

#[test]
fn shared_constants_agree() {
    let project = module_named("project int64");
    assert_eq!(wgsl_const(&project, "GROUP_SIZE"), GROUP_SIZE as u64);
    assert_eq!(wgsl_const(&project, "EMPTY"), EMPTY as u64);
    use super::projection::{
        FILTER_CLASSES, FILTER_CLIP, FILTER_ELEVATION, FILTER_INTENSITY, FILTER_MARKED,
        FILTER_RETURN,
    };
    for (name, v) in [
        ("FILTER_MARKED", FILTER_MARKED),
        ("MARK_HIDDEN", crate::marks::MARK_HIDDEN),
        ("RETURN_ABOVE_15", crate::marks::RETURN_ABOVE_15),
        ("FILTER_CLIP", FILTER_CLIP),
        ("FILTER_CLASSES", FILTER_CLASSES),
        ("FILTER_INTENSITY", FILTER_INTENSITY),
        ("FILTER_ELEVATION", FILTER_ELEVATION),
        ("FILTER_RETURN", FILTER_RETURN),
    ] {
        assert_eq!(wgsl_const(&project, name), v as u64, "{name}");
    }
}

#[test]
fn workgroup_sizes_match_the_dispatches() {
    // Point passes dispatch GROUP_SIZE threads a group; full-screen passes PIXEL_GROUP².
    for s in all_shaders(true) {
        let module = parse(&s);
        let Some(entry) = module.entry_points.iter().find(|e| e.name == s.entry) else {
            continue;
        };
        let points = s.label == "clear"
            || s.label.starts_with("project")
            || s.label.starts_with("surfel depth")
            || s.label.starts_with("surfel blend");
        let pixels = ["finish", "shade", "resolve", "unpack"]
            .iter()
            .any(|k| s.label.ends_with(k));
        if points {
            assert_eq!(entry.workgroup_size, [GROUP_SIZE, 1, 1], "{}", s.label);
        } else if pixels {
            assert_eq!(
                entry.workgroup_size,
                [PIXEL_GROUP, PIXEL_GROUP, 1],
                "{}",
                s.label
            );
        }
    }
}

/// The projection resolves its colour plane only for a pipeline that declares it reads it: one
/// whose shaders bind the plane (a global `colours`, as the projection's resolve names it) and
/// declared otherwise would read an unwritten plane.
#[test]
fn a_pipeline_that_binds_the_colour_plane_declares_it_reads_it() {
    for p in REGISTRY {
        for s in (p.shaders)(true).iter().chain((p.shaders)(false).iter()) {
            let module = parse(s);
            let binds = module
                .global_variables
                .iter()
                .any(|(_, g)| g.name.as_deref() == Some("colours"));
            assert!(
                !binds || p.reads_colour_plane,
                "{}: module {} binds the colour plane but the pipeline does not declare \
                 reads_colour_plane",
                p.name,
                s.label
            );
        }
    }
}

/// Where a value array (a `let`, a function argument) is indexed by a variable, naga copies the
/// whole array into a function variable at each such access. NVIDIA's driver (580, H200) never
/// finished compiling the pyramid's HPR module written that way, its 6x6 cells of 16 bytes
/// passed by value to the functions picking their rings; such arrays belong in a `var`, passed
/// by pointer. Small ones (the eight directions of a ring, up to 64 bytes) compiled at once.
#[test]
fn no_large_value_array_is_indexed_by_a_variable() {
    const LARGEST_COPIED: u32 = 64;
    let caps = Capabilities::SHADER_INT64 | Capabilities::SHADER_INT64_ATOMIC_MIN_MAX;
    for s in all_shaders(true) {
        let module = parse(&s);
        let info = Validator::new(ValidationFlags::all(), caps)
            .validate(&module)
            .unwrap_or_else(|e| panic!("{}: {e}", s.label));
        let functions = module.functions.iter().map(|(h, f)| (f, &info[h]));
        let entries = module
            .entry_points
            .iter()
            .enumerate()
            .map(|(i, e)| (&e.function, info.get_entry_point(i)));
        for (function, function_info) in functions.chain(entries) {
            for (_, expression) in function.expressions.iter() {
                let naga::Expression::Access { base, .. } = *expression else {
                    continue;
                };
                let ty = function_info[base].ty.inner_with(&module.types);
                let bytes = ty.size(module.to_ctx());
                assert!(
                    !matches!(ty, naga::TypeInner::Array { .. }) || bytes <= LARGEST_COPIED,
                    "{}: function {} indexes a value array of {bytes} bytes by a variable",
                    s.label,
                    function.name.as_deref().unwrap_or("(entry point)")
                );
            }
        }
    }
}

/// A buffer of `bytes` for a test kernel to write and `run_kernel` to read back.
pub(crate) fn kernel_output(device: &wgpu::Device, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("kernel output"),
        size: bytes,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    })
}

/// Runs a test kernel over `threads` threads (workgroups of 64) with `groups` bound as groups
/// 0, 1, ..., and reads back `output` whole.
pub(crate) fn run_kernel(
    ctx: &crate::gpu::GpuContext,
    pipe: &wgpu::ComputePipeline,
    groups: &[wgpu::BindGroup],
    threads: usize,
    output: &wgpu::Buffer,
) -> Vec<u8> {
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(pipe);
        for (k, g) in groups.iter().enumerate() {
            pass.set_bind_group(k as u32, g, &[]);
        }
        pass.dispatch_workgroups((threads as u32).div_ceil(64), 1, 1);
    }
    ctx.queue.submit([encoder.finish()]);
    crate::gpu::readback::read_buffer(ctx, output, output.size()).expect("kernel output readback")
}

/// The loops of a WGSL text, comments taken out: the keyword each starts with, and for a `for`
/// whether its header has a condition.
fn loops_of(wgsl: &str) -> Vec<(&'static str, bool)> {
    let code: String = wgsl
        .lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n");
    let words: Vec<(usize, &str)> = code
        .match_indices(|c: char| !(c.is_alphanumeric() || c == '_'))
        .scan(0, |start, (at, sep)| {
            let word = (*start, &code[*start..at]);
            *start = at + sep.len();
            Some(word)
        })
        .filter(|(_, w)| matches!(*w, "for" | "while" | "loop"))
        .collect();
    words
        .into_iter()
        .map(|(at, w)| match w {
            "for" => {
                // The text between the header's two semicolons, at the header's own depth.
                let header = &code[at..];
                let (mut depth, mut semis, mut condition) = (0, 0, String::new());
                for c in header.chars() {
                    match c {
                        '(' => depth += 1,
                        ')' if depth == 1 => break,
                        ')' => depth -= 1,
                        ';' if depth == 1 => semis += 1,
                        _ if semis == 1 => condition.push(c),
                        _ => {}
                    }
                }
                ("for", !condition.trim().is_empty())
            }
            "while" => ("while", true),
            _ => ("loop", false),
        })
        .collect()
}

/// Every `.wgsl` file under `dir`, with its path.
fn wgsl_files(dir: &std::path::Path, out: &mut Vec<(std::path::PathBuf, String)>) {
    for entry in std::fs::read_dir(dir).expect("a source folder") {
        let path = entry.expect("an entry").path();
        if path.is_dir() {
            wgsl_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "wgsl") {
            let text = std::fs::read_to_string(&path).expect("a WGSL file");
            out.push((path, text));
        }
    }
}

/// The pipelines' modules are made without naga's loop bound (`ShaderSource::module`), so a
/// loop that never ended would be undefined behaviour on the GPU. Each loop in every WGSL file
/// of the viewer must take a form that ends: a `for` with a condition over a count, or the one
/// binary search; a `loop`, a `while` elsewhere, or a `for` without a condition must be shown
/// to end before it is let in here. (The form alone does not prove a `for` ends: its
/// condition must be on a counter its step advances, and its bound clamped on the CPU.)
#[test]
fn viewer_loops_take_a_form_that_ends() {
    let mut files = Vec::new();
    wgsl_files(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src"),
        &mut files,
    );
    let mut seen_for = 0;
    for (path, text) in &files {
        let is_search = path.ends_with("range_search.wgsl");
        for (kind, bounded) in loops_of(text) {
            let at = path.display();
            match kind {
                "for" => {
                    assert!(bounded, "{at}: a `for` loop without a condition");
                    seen_for += 1;
                }
                "while" => assert!(is_search, "{at}: a `while` loop"),
                _ => panic!("{at}: a `loop` statement"),
            }
        }
    }
    assert!(files.len() > 40, "only {} WGSL files found", files.len());
    assert!(seen_for > 20, "the scan found only {seen_for} `for` loops");
    assert_eq!(
        loops_of("for (var i = 0; ; i++) {} // loop\nloop { break; } while x {}"),
        vec![("for", false), ("loop", false), ("while", true)]
    );
}
