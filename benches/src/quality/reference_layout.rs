//! The reference mesh's uniforms, as Rust writes them, against the layout its WGSL reads.

use super::{SHADER, Uniforms};

#[test]
fn the_uniforms_match_the_shader() {
    let module = naga::front::wgsl::parse_str(&format!(
        "{}\n{SHADER}",
        strata_viewer::pipelines::LIGHTING_WGSL
    ))
    .expect("the reference shader parses");
    let (span, members) = module
        .types
        .iter()
        .find_map(|(_, t)| match &t.inner {
            naga::TypeInner::Struct { members, span } if t.name.as_deref() == Some("Uniforms") => {
                Some((*span, members.clone()))
            }
            _ => None,
        })
        .expect("a struct Uniforms");
    let offsets: Vec<(String, u32)> = members
        .iter()
        .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
        .collect();
    let rust = [
        ("view_proj", std::mem::offset_of!(Uniforms, view_proj)),
        ("view", std::mem::offset_of!(Uniforms, view)),
        ("light", std::mem::offset_of!(Uniforms, light)),
        ("width", std::mem::offset_of!(Uniforms, width)),
    ]
    .map(|(n, o)| (n.to_string(), o as u32));
    assert_eq!(offsets, rust);
    assert_eq!(span as usize, std::mem::size_of::<Uniforms>());
}
