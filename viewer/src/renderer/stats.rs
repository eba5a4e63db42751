//! What one frame reports: `--stats` writes it, the panel shows it.

use crate::gpu::timing::PassTimes;
use serde::Serialize;
use std::collections::BTreeMap;

/// Statistics of one frame, as `--stats` writes them and the panel shows them.
#[derive(Debug, Clone, Default, Serialize)]
pub struct FrameStats {
    pub frame: u64,
    pub points_drawn: u64,
    /// The points the frame could draw: the settings' budget, or fewer where the GPU cache
    /// (`--gpu-cache`) holds fewer.
    pub budget_drawn: u64,
    pub nodes_drawn: usize,
    /// CPU time of the frame, including waiting for the GPU where the caller waited.
    pub frame_ms: f64,
    /// The pipeline that drew the frame.
    pub pipeline: &'static str,
    /// Its parameters this frame, automatic ones resolved (absent: automatic, and nothing was
    /// drawn to take the value from).
    pub params: BTreeMap<&'static str, f32>,
    /// What the pipeline measured (the pyramid's `depth_noise`, a deviation in dataset
    /// units). In a window the latest that has arrived, a frame or more behind; headless, this
    /// frame's.
    pub measures: BTreeMap<&'static str, f32>,
    /// What the pipeline has to say about the frame (a fallback it took), if anything.
    pub note: Option<&'static str>,
    /// GPU ms per pass, by `pass_clock`, in the order the passes ran.
    pub passes: PassTimes,
    /// "timestamps" (queries inside the frame) or "wall" (each pass submitted alone and
    /// waited for).
    pub pass_clock: &'static str,
    /// Stored bytes that arrived from the loaders during this frame.
    pub bytes_loaded: u64,
    pub bytes_loaded_total: u64,
    /// Nodes that could not be loaded (corrupt, unreadable), over the whole session.
    pub nodes_failed: usize,
    pub pages_failed: usize,
    /// Nodes the view wants that are not resident yet.
    pub nodes_missing: usize,
    /// Of those, nodes whose source did not answer; they are asked for again later.
    pub nodes_unavailable: usize,
    /// Fetches that failed for want of an answer (server gone, timeouts), over the session.
    pub fetch_errors: u64,
    pub nodes_visible: usize,
    pub nodes_resident: usize,
    pub nodes_in_flight: usize,
    pub nodes_queued: usize,
    pub gpu_bytes: u64,
    /// Every node the view and budget call for is resident and drawn (and, where the
    /// normals mark a surface's sides, drawn with the facing check of this view).
    pub complete: bool,
    /// Which side of the surfaces the stored normals point to, as the facing check found:
    /// "as stored", "turned" (into the surfaces: each is turned before use) or "mixed" (no
    /// side: nothing is culled); absent where the check does not run (the normals mark no
    /// sides, or the pipeline reads none).
    pub normal_sides: Option<&'static str>,
}
