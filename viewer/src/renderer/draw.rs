//! Drawing one frame: the screen and the active pipeline's buffers for its size, the frame
//! uniforms (filters and clip boxes among them), then the projection and the pipeline's passes
//! inside one error scope.

use super::{Guard, Renderer};
use crate::ViewerError;
use crate::camera::Camera;
use crate::dataset::sampling::covering_radius;
use crate::lod::{Selection, Tree, clip_range};
use crate::pipelines::params::ResolvedParams;
use crate::pipelines::projection::{
    ArenaDraw, FINISH_SLOTS, FrameDraw, FrameUniforms, GpuRange, NormalSides,
};
use crate::pipelines::{PipelineFrame, PipelineInfo, PointStream, ViewFrame};
use crate::settings::{Settings, SizeMode};
use std::collections::{BTreeMap, HashMap, HashSet};
use strata_format::NodeKey;

impl Renderer {
    /// Makes the screen and the active pipeline's buffers for this size, guard band and
    /// pipeline.
    fn prepare_screen(
        &mut self,
        info: &'static PipelineInfo,
        guard: Guard,
    ) -> Result<(), ViewerError> {
        self.check_guarded(info, guard)?;
        let (width, height) = guard.padded();
        let resized = self.guard != guard
            || self
                .screen
                .as_ref()
                .is_none_or(|s| s.width != width || s.height != height);
        let switched = self.active != Some(info.name);
        if resized || switched {
            // Free what the old pipeline made before making anything new: both at once may not
            // fit. What it measured or timed describes another picture.
            if let Some(old) = self.active.take().and_then(|n| self.pipelines.get_mut(n)) {
                old.release_targets();
            }
            self.measures.clear();
            self.timer.discard_pending();
            self.previous_view = None;
        }
        // The previous depth plane exists exactly while the pipeline keeps the previous frame.
        let previous_mismatch = self
            .screen
            .as_ref()
            .is_some_and(|s| s.previous_depths.is_some() != info.previous_frame);
        if resized || previous_mismatch {
            (self.screen, self.shown) = (None, None);
            let (ctx, projection) = (&self.ctx, &self.projection);
            let (screen, shown) =
                ctx.scoped(&format!("making a {width}x{height} screen"), || {
                    let screen = projection.screen(
                        &ctx.device,
                        &ctx.queue,
                        width,
                        height,
                        info.previous_frame,
                    );
                    (screen, guard.shown_texture(&ctx.device))
                })?;
            (self.screen, self.shown, self.guard) = (Some(screen), shown, guard);
        }
        if self.active != Some(info.name) {
            let (Some(screen), Some(p)) = (&self.screen, self.pipelines.get_mut(info.name)) else {
                return Err(ViewerError::Gpu(format!(
                    "the {} pipeline is not ready",
                    info.name
                )));
            };
            let what = format!(
                "making the {} pipeline's {width}x{height} buffers",
                info.name
            );
            self.ctx
                .scoped(&what, || p.make_targets(&self.ctx.device, screen))?;
            self.active = Some(info.name);
        }
        Ok(())
    }

    /// The drawn ranges of `keys` per arena, each with what the LOD drew below its node.
    fn arena_draws(&self, keys: &[NodeKey]) -> Vec<ArenaDraw> {
        let drawn: HashSet<NodeKey> = keys.iter().copied().collect();
        let mut complete = HashMap::new();
        let mut per_arena: BTreeMap<u32, ArenaDraw> = BTreeMap::new();
        for key in keys {
            let centre = self.ds.node_centre(*key).to_array();
            // A node the tree does not know counts as having every child, and a child it does
            // not know as having children: the points then stand for theirs.
            let exist = self.tree.node(*key).map_or(0xff, |n| n.child_mask as u32);
            let children = (0..8u8).fold(exist << 8, |mask, c| {
                let child = key.child(c);
                let is_drawn = u32::from(drawn.contains(&child));
                let whole = drawn_to_the_leaves(&self.tree, &drawn, child, &mut complete);
                mask | is_drawn << c | u32::from(whole) << (16 + c)
            });
            // A leaf's points are all there is, at whatever density the scan left: drawn at
            // least as wide as discs that cover the density they were measured at, not at its
            // level's spacing, which says nothing of them.
            let level = self.ds.node_spacing(*key);
            let spacing = match self.tree.sampling(*key) {
                Some(s) if exist == 0 => level.max(covering_radius(s)),
                _ => level,
            };
            for p in self.cache.pieces(*key).unwrap_or_default() {
                let d = per_arena.entry(p.arena).or_insert_with(|| ArenaDraw {
                    arena: p.arena,
                    ranges: Vec::new(),
                });
                d.ranges.push(GpuRange {
                    start: p.start,
                    count: p.count,
                    first_group: 0,
                    spacing,
                    centre,
                    children,
                });
            }
        }
        per_arena.into_values().collect()
    }

    /// Draws the selection; returns whether the frame took the facing check of its own view,
    /// and the sides it drew with; `None` where it needs none (its normals mark no sides, or
    /// the pipeline reads none).
    pub(super) fn draw(
        &mut self,
        camera: &Camera,
        guard: Guard,
        settings: &Settings,
        (sel, extra): (&Selection, Option<&Selection>),
        params: &ResolvedParams,
    ) -> Result<Option<(bool, NormalSides)>, ViewerError> {
        let info = settings.pipeline;
        self.prepare_screen(info, guard)?;
        let (width, height) = guard.padded();
        let draws = self.arena_draws(&sel.draw);
        // The extra view's nodes beside the drawn ones, each once.
        let casters = match extra {
            Some(e) => {
                let drawn: HashSet<NodeKey> = sel.draw.iter().copied().collect();
                let mut keys = sel.draw.clone();
                keys.extend(e.draw.iter().filter(|k| !drawn.contains(k)));
                Some(self.arena_draws(&keys))
            }
            None => None,
        };
        let aspect = width as f32 / height as f32;
        let (near, far) = clip_range(&self.ds, camera, aspect);
        let view_proj = camera.projection(aspect, near, far) * camera.view();
        let (bmin, bmax) = self.ds.bounds();
        let [r, g, b] = settings.background;
        let mut uniforms = FrameUniforms {
            view_proj: view_proj.to_cols_array_2d(),
            width,
            height,
            point_size: settings.point_size,
            size_mode: match settings.size_mode {
                SizeMode::Fixed => 0,
                SizeMode::Attenuated => 1,
            },
            focal_px: camera.focal_px(height),
            colour_mode: self.ds.shader_colour(settings.colour).shader_code(),
            z_min: bmin.z,
            z_max: bmax.z,
            arena_shift: self.cache.arena_shift,
            background: r as u32 | (g as u32) << 8 | (b as u32) << 16 | 255 << 24,
            clip_count: 0,
            footprint: 0.0,
            shading: [0.0; 4],
            arena_slots: [u32::MAX; FINISH_SLOTS],
            intensity_scale: (1.0 / self.ds.intensity_max().max(1e-9)) as f32,
            filters: 0,
            return_lo: 0,
            return_hi: 0,
            ranges: [0.0; 4],
            class_mask: [[0; 4]; 2],
            clip_boxes: [[0.0; 4]; 8],
            eye: camera.view().inverse().w_axis.to_array(),
            normals_turned: 0,
            near,
            far,
            pad: [0; 1],
        };
        // The loader marks what the word cannot answer (`StreamDataset::marks`).
        let marked = !self.loader.form().1.is_empty();
        set_filter(
            &mut uniforms,
            &settings.filter,
            self.ds.anchor(),
            (self.ds.word_fit(), marked),
        );
        let wall = self.wall_clock(settings);
        let (Some(screen), Some(pipeline)) = (&self.screen, self.pipelines.get_mut(info.name))
        else {
            return Err(ViewerError::Gpu(format!(
                "the {} pipeline is not ready",
                info.name
            )));
        };
        pipeline.uniforms(params, &mut uniforms);
        let view = ViewFrame {
            view: camera.view(),
            view_proj,
            fov_y: camera.fov_y,
            near,
            far,
            focal_px: camera.focal_px(height),
            aspect,
        };
        // Where the normals mark a surface's sides, the facing check says which side they point
        // to; the frame takes the verdict so far.
        let with_normals = info.streams.contains(&PointStream::Normals);
        let checks_facing = self.ds.normals_mark_back_faces() && with_normals;
        let sides = match checks_facing {
            true => self.facing.sides(),
            false => NormalSides::AsStored,
        };
        uniforms.normals_turned = u32::from(sides == NormalSides::Turned);
        let key = view_key(&uniforms, &sel.draw);
        let drawn_facing = checks_facing.then(|| (self.facing.settled(key), sides));
        let has_normals = self.ds.has_normals();
        let normals_outward = self.ds.normals_face_outward() && sides.mark_sides();
        let marks_back_faces = self.ds.normals_mark_back_faces() && sides.mark_sides();
        let cull = info.cull_back_faces && marks_back_faces && with_normals;
        let (ctx, projection, cache, timer, count, facing, shown) = (
            &self.ctx,
            &self.projection,
            &self.cache,
            &mut self.timer,
            &mut self.drawn_count,
            &mut self.facing,
            &self.shown,
        );
        let int64 = screen.keys.is_some() && !settings.force_int32;
        // Until this frame is drawn, no colour plane is known to be this frame's.
        self.last_colour_plane = false;
        let fused = ctx.scoped(&format!("drawing with the {} pipeline", info.name), || {
            let mut encoder = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("frame"),
                });
            timer.begin_frame(wall);
            let finished = projection.encode(
                ctx,
                &mut encoder,
                screen,
                cache,
                &FrameDraw {
                    uniforms: &uniforms,
                    arenas: &draws,
                    // The fused finish writes no depth plane for the next frame to keep.
                    allow_fused: settings.fused_finish && !info.previous_frame,
                    force_int32: settings.force_int32,
                    fused: pipeline.fused(params),
                    cull_back_faces: cull,
                    resolve_colours: info.reads_colour_plane,
                    // The kept depth of the previous frame is copied from the planes.
                    unpack_planes: info.reads_planes || info.previous_frame,
                },
                count,
                timer,
            );
            if checks_facing {
                facing.encode(&ctx.device, &mut encoder, screen, cache, &draws, key, timer);
            }
            if !finished {
                let frame = PipelineFrame {
                    ctx,
                    screen,
                    cache,
                    arenas: &draws,
                    casters: casters.as_deref().unwrap_or(&draws),
                    params,
                    view: &view,
                    previous: self.previous_view.filter(|_| info.previous_frame),
                    int64,
                    has_normals,
                    normals_outward,
                    normals_mark_back_faces: marks_back_faces,
                    back_faces_culled: cull,
                    curvature_scale: self.ds.curvature_scale().map(|c| c as f32),
                    bounds: [bmin, bmax],
                    filters_key: filters_key(&uniforms),
                };
                pipeline.encode(&frame, &mut encoder, timer)?;
            }
            if info.previous_frame {
                screen.keep_depths(&mut encoder, pipeline.kept_depth());
            }
            if let Some(shown) = shown {
                guard.copy_shown(&mut encoder, &screen.output, shown);
            }
            timer.resolve(&mut encoder);
            ctx.queue.submit([encoder.finish()]);
            timer.after_submit();
            count.after_submit();
            facing.after_submit();
            pipeline.after_submit();
            Ok::<bool, ViewerError>(finished)
        });
        // A frame that failed on the way was never submitted: the copies it recorded will not
        // arrive, and must not keep the next ones from being recorded.
        let fused = match fused {
            Ok(Ok(finished)) => finished,
            Ok(Err(e)) | Err(e) => {
                self.drawn_count.abandon();
                self.facing.abandon();
                return Err(e);
            }
        };
        self.last_int64 = int64;
        self.last_fused = fused;
        self.last_colour_plane = !fused && info.reads_colour_plane;
        self.previous_view = Some(view);
        if let Some(e) = self.timer.take_poll_error() {
            return Err(ViewerError::Gpu(format!("waiting for the GPU failed: {e}")));
        }
        // Non-blocking: lets map callbacks of earlier frames run.
        self.ctx
            .device
            .poll(wgpu::PollType::Poll)
            .map_err(|e| ViewerError::Gpu(format!("polling the GPU failed: {e}")))?;
        Ok(drawn_facing)
    }
}

/// A hash of what the facing check sees: the view, the screen, the filters and the drawn nodes.
fn view_key(u: &FrameUniforms, drawn: &[NodeKey]) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::hash::DefaultHasher::new();
    (filters_key(u), u.width, u.height, drawn).hash(&mut h);
    for v in u.view_proj.iter().flatten() {
        v.to_bits().hash(&mut h);
    }
    h.finish()
}

/// A hash of the frame's point filters and clip boxes as the GPU applies them.
fn filters_key(u: &FrameUniforms) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::hash::DefaultHasher::new();
    (u.filters, u.return_lo, u.return_hi, u.clip_count).hash(&mut h);
    u.class_mask.hash(&mut h);
    for v in u.ranges.iter().chain(u.clip_boxes.iter().flatten()) {
        v.to_bits().hash(&mut h);
    }
    h.finish()
}

/// Puts `filter` into the frame's uniforms; `anchor_z` is the elevation the GPU's z is relative to.
/// The frame's filters the GPU answers; those the attribute word cannot answer exactly for this
/// dataset (`fit`) the loader has marked instead (`StreamDataset::marks`).
fn set_filter(
    u: &mut FrameUniforms,
    filter: &crate::settings::PointFilter,
    anchor: glam::DVec3,
    (fit, marked): (crate::marks::WordFit, bool),
) {
    use crate::pipelines::projection::{
        FILTER_CLASSES, FILTER_CLIP, FILTER_ELEVATION, FILTER_INTENSITY, FILTER_RETURN,
    };
    let anchor_z = anchor.z;
    for (k, clip) in filter
        .clips
        .iter()
        .take(crate::settings::ClipBox::MAX)
        .enumerate()
    {
        u.filters |= FILTER_CLIP;
        let rel = |v: [f64; 3]| (glam::DVec3::from_array(v) - anchor).as_vec3();
        let (lo, hi) = (rel(clip.min), rel(clip.max));
        u.clip_boxes[2 * k] = [lo.x, lo.y, lo.z, if clip.outside { 1.0 } else { 0.0 }];
        u.clip_boxes[2 * k + 1] = [hi.x, hi.y, hi.z, 0.0];
        u.clip_count = k as u32 + 1;
    }
    if let Some(mask) = filter.classes.filter(|_| fit.classes) {
        u.filters |= FILTER_CLASSES;
        u.class_mask = [
            [mask[0], mask[1], mask[2], mask[3]],
            [mask[4], mask[5], mask[6], mask[7]],
        ];
    }
    if let Some((lo, hi)) = filter.intensity.filter(|_| fit.intensity) {
        u.filters |= FILTER_INTENSITY;
        // Whole numbers of 16 bits, which f32 holds exactly.
        u.ranges[0] = lo.ceil() as f32;
        u.ranges[1] = hi.floor() as f32;
    }
    if let Some((lo, hi)) = filter.elevation {
        u.filters |= FILTER_ELEVATION;
        // Rounded to f32 as the points' positions are (relative to the anchor; rounding keeps
        // order, so no point within the bounds falls outside), widened by a few f64 steps only
        // for the two subtractions' own rounding.
        let slack = |v: f64| v.abs().max(1.0) * 1e-12;
        u.ranges[2] = (lo - anchor_z - slack(lo - anchor_z)) as f32;
        u.ranges[3] = (hi - anchor_z + slack(hi - anchor_z)) as f32;
    }
    if let Some((lo, hi)) = filter.return_number.filter(|_| fit.return_number) {
        u.filters |= FILTER_RETURN;
        u.return_lo = lo;
        u.return_hi = hi;
    }
    if marked {
        u.filters |= crate::pipelines::projection::FILTER_MARKED;
    }
}

/// Whether `key` is drawn and so is every node below it, down to the leaves: then every point
/// the dataset has there is drawn, and its points need no more than their stored radii.
/// Memoised in `known`, since a frame asks of each node's children.
fn drawn_to_the_leaves(
    tree: &Tree,
    drawn: &HashSet<NodeKey>,
    key: NodeKey,
    known: &mut HashMap<NodeKey, bool>,
) -> bool {
    if let Some(&w) = known.get(&key) {
        return w;
    }
    let whole = drawn.contains(&key)
        && tree.node(key).is_some_and(|n| {
            (0..8u8)
                .filter(|c| n.child_mask & (1 << c) != 0)
                .all(|c| drawn_to_the_leaves(tree, drawn, key.child(c), known))
        });
    known.insert(key, whole);
    whole
}
