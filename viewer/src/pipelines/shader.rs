//! Shader modules as the viewer composes them: the shared frame declarations, then the parts.
//! The same `ShaderSource` is compiled by the pipelines and validated by naga in the tests, so
//! the test sees exactly what the GPU gets.

use super::projection::FRAME_WGSL;

/// One compute shader module: its parts, in order, after `frame.wgsl`, and the values its
/// pipeline gives the module's `override` constants.
#[derive(Debug, Clone)]
pub struct ShaderSource {
    pub label: &'static str,
    pub entry: &'static str,
    pub parts: Vec<&'static str>,
    /// Pipeline-overridable constants by name. A branch on one is gone from the compiled
    /// pipeline, where a branch on a uniform stays: a software adapter (lavapipe) runs both
    /// sides of every branch for all pixels, so a pass that holds code for several modes pays
    /// for all of them (the filters' shade at 1280x720: 36.7 ms with every mode's code, 28-29
    /// ms with the default mode's alone).
    pub constants: Vec<(&'static str, f64)>,
}

impl ShaderSource {
    pub fn new(label: &'static str, parts: &[&'static str]) -> ShaderSource {
        ShaderSource {
            label,
            entry: "main",
            parts: parts.to_vec(),
            constants: Vec::new(),
        }
    }

    pub fn with_entry(mut self, entry: &'static str) -> ShaderSource {
        self.entry = entry;
        self
    }

    /// Gives the module's `override` constant `name` the value `value` (a bool as 0 or 1).
    pub fn with_constant(mut self, name: &'static str, value: f64) -> ShaderSource {
        self.constants.push((name, value));
        self
    }

    /// The whole WGSL text.
    pub fn compose(&self) -> String {
        let mut src = String::from(FRAME_WGSL);
        for p in &self.parts {
            src.push('\n');
            src.push_str(p);
        }
        src
    }

    pub fn module(&self, device: &wgpu::Device) -> wgpu::ShaderModule {
        let descriptor = wgpu::ShaderModuleDescriptor {
            label: Some(self.label),
            source: wgpu::ShaderSource::Wgsl(self.compose().into()),
        };
        // Every check stays but the loop bound naga adds to each loop, whose counter keeps
        // the driver from unrolling the short fixed loops over a pixel's neighbours: on
        // lavapipe the filters' fill takes about a fifth less (README, Benchmarks).
        // SAFETY: the bound guards against a loop that never ends, which a driver may take
        // for unreachable code. Every loop in the viewer's WGSL ends: each is a `for` whose
        // condition is on a counter its step advances, up to a bound the CPU clamps (search
        // radius, rings, pyramid levels, clip count), or the binary search of
        // range_search.wgsl, whose interval shrinks each step
        // (`viewer_loops_take_a_form_that_ends` checks that no other kind of loop comes in).
        let checks = wgpu::ShaderRuntimeChecks {
            force_loop_bounding: false,
            ..wgpu::ShaderRuntimeChecks::checked()
        };
        unsafe { device.create_shader_module_trusted(descriptor, checks) }
    }

    /// A compute pipeline of this module's entry point; `layout: None` derives the layout
    /// from the shader.
    pub fn compute(
        &self,
        device: &wgpu::Device,
        layout: Option<&wgpu::PipelineLayout>,
    ) -> wgpu::ComputePipeline {
        let module = self.module(device);
        device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(self.label),
            layout,
            module: &module,
            entry_point: Some(self.entry),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &self.constants,
                ..Default::default()
            },
            cache: None,
        })
    }
}

/// Pipelines compiled per value of their `override` constants (a key), as frames ask for them:
/// a parameter that changes a pass's code compiles its variant once, and switching back finds
/// it here.
pub struct Variants<K, P> {
    compiled: Vec<(K, P)>,
}

impl<K: PartialEq + Copy, P> Variants<K, P> {
    /// With `first`, compiled up front with the pipeline's other passes.
    pub fn new(key: K, first: P) -> Variants<K, P> {
        Variants {
            compiled: vec![(key, first)],
        }
    }

    /// The variant of `key`, made by `make` the first time.
    pub fn get(&mut self, key: K, make: impl FnOnce(K) -> P) -> &P {
        let at = match self.compiled.iter().position(|(k, _)| *k == key) {
            Some(at) => at,
            None => {
                self.compiled.push((key, make(key)));
                self.compiled.len() - 1
            }
        };
        &self.compiled[at].1
    }
}
