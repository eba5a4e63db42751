//! The shape of the hidden-point removal pass (pyramid_hpr.wgsl), chosen per adapter.

// The block shape takes one reach for its 4x4 pixels from the coarse level's depth: they share
// a cell from level 2 up.
const _: () = assert!(super::COARSE_LEVEL >= 2);

/// How the HPR pass spreads the pixels over its invocations. Both give the same labels; each is
/// the faster where it is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HprShape {
    /// One pixel an invocation, for GPUs: on an H200 at 1280x720 the pass took 0.03 ms where
    /// the block took 0.07, and the driver compiled it in 80 ms where the block took 1.7 s.
    Pixel,
    /// A 4x4 block an invocation, each neighbour read once for sixteen pixels, for CPU
    /// adapters: on lavapipe it took 18 ms where one pixel an invocation took 33.
    Block,
}

impl HprShape {
    pub const ALL: [HprShape; 2] = [HprShape::Pixel, HprShape::Block];

    pub fn for_device(device_type: wgpu::DeviceType) -> HprShape {
        if device_type == wgpu::DeviceType::Cpu {
            HprShape::Block
        } else {
            HprShape::Pixel
        }
    }

    pub(super) fn module(self) -> &'static str {
        match self {
            HprShape::Pixel => "hpr",
            HprShape::Block => "hpr block",
        }
    }

    /// Pixels along each side of what one invocation labels.
    pub(super) fn side(self) -> u32 {
        match self {
            HprShape::Pixel => 1,
            HprShape::Block => 4,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::HprShape;
    use wgpu::DeviceType;

    #[test]
    fn cpu_adapters_take_the_block_and_gpus_one_pixel_an_invocation() {
        assert_eq!(HprShape::for_device(DeviceType::Cpu), HprShape::Block);
        for gpu in [
            DeviceType::DiscreteGpu,
            DeviceType::IntegratedGpu,
            DeviceType::VirtualGpu,
            DeviceType::Other,
        ] {
            assert_eq!(HprShape::for_device(gpu), HprShape::Pixel, "{gpu:?}");
        }
    }
}
