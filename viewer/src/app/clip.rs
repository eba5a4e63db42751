//! The panel's clip boxes: added around the point looked at, sized and moved with handles in the
//! scene (one on each face, one at the centre that moves the box across the ground) or with
//! numbers in the panel, each keeping its inside or its outside, each removable. They are the
//! same `ClipBox`es as `--clip`: applied in the projection and bounding what is loaded.

use super::ViewerApp;
use crate::overlay::ScreenProjector;
use crate::settings::ClipBox;
use eframe::egui;
use glam::DVec3;

/// A handle of clip box `index`: the face on `axis` at its minimum or maximum, or the centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Handle {
    Face {
        index: usize,
        axis: usize,
        max: bool,
    },
    Centre {
        index: usize,
    },
}

/// Pixels from a handle a press grabs it.
const GRAB_PX: f32 = 10.0;
const COLOUR: egui::Color32 = egui::Color32::from_rgb(255, 120, 60);

/// Where each handle of `boxes` lies on screen, in image pixels.
pub fn handles(proj: &ScreenProjector, boxes: &[ClipBox]) -> Vec<([f32; 2], Handle)> {
    let mut out = Vec::new();
    for (index, b) in boxes.iter().enumerate() {
        let c: [f64; 3] = std::array::from_fn(|k| (b.min[k] + b.max[k]) / 2.0);
        if let Some(p) = proj.to_pixel(c) {
            out.push((p, Handle::Centre { index }));
        }
        for axis in 0..3 {
            for max in [false, true] {
                let mut at = c;
                at[axis] = if max { b.max[axis] } else { b.min[axis] };
                if let Some(p) = proj.to_pixel(at) {
                    out.push((p, Handle::Face { index, axis, max }));
                }
            }
        }
    }
    out
}

/// Where along the line through `at` on `axis` the ray through pixel `to` passes closest
/// (the step from `at`), `None` where the line is seen end on.
fn along_axis(proj: &ScreenProjector, at: [f64; 3], axis: usize, to: [f32; 2]) -> Option<f64> {
    let (o, d) = proj.ray(to)?;
    let mut e = DVec3::ZERO;
    e[axis] = 1.0;
    let w = DVec3::from_array(at) - o;
    // Closest points of the lines at + s e and o + t d.
    let b = e.dot(d);
    let denom = 1.0 - b * b;
    if denom < 1e-6 {
        return None;
    }
    let s = (b * w.dot(d) - w.dot(e)) / denom;
    s.is_finite().then_some(s)
}

/// Moves `handle` of `boxes` by `drag` image pixels: a face along its axis to where the cursor
/// points (never past the opposite face), the centre across the horizontal plane through it.
pub fn drag_handle(proj: &ScreenProjector, boxes: &mut [ClipBox], handle: Handle, drag: [f32; 2]) {
    let index = match handle {
        Handle::Face { index, .. } | Handle::Centre { index } => index,
    };
    let Some(b) = boxes.get_mut(index) else {
        return;
    };
    let c: [f64; 3] = std::array::from_fn(|k| (b.min[k] + b.max[k]) / 2.0);
    match handle {
        Handle::Face { axis, max, .. } => {
            let mut at = c;
            at[axis] = if max { b.max[axis] } else { b.min[axis] };
            let Some(from) = proj.to_pixel(at) else {
                return;
            };
            let to = [from[0] + drag[0], from[1] + drag[1]];
            let Some(d) = along_axis(proj, at, axis, to) else {
                return;
            };
            if max {
                b.max[axis] = (b.max[axis] + d).max(b.min[axis]);
            } else {
                b.min[axis] = (b.min[axis] + d).min(b.max[axis]);
            }
        }
        Handle::Centre { .. } => {
            let Some(from) = proj.to_pixel(c) else { return };
            let to = [from[0] + drag[0], from[1] + drag[1]];
            let Some((o, d)) = proj.ray(to) else { return };
            // Where the ray meets the plane z = centre (not from below or edge on).
            if d.z.abs() < 1e-6 {
                return;
            }
            let t = (c[2] - o.z) / d.z;
            if !(t > 0.0 && t.is_finite()) {
                return;
            }
            let hit = o + d * t;
            for (k, w) in [(0, hit.x - c[0]), (1, hit.y - c[1])] {
                b.min[k] += w;
                b.max[k] += w;
            }
        }
    }
}

/// The twelve edges of a box.
fn edges(b: &ClipBox) -> Vec<([f64; 3], [f64; 3])> {
    let corner = |i: usize| -> [f64; 3] {
        std::array::from_fn(|k| if i >> k & 1 == 1 { b.max[k] } else { b.min[k] })
    };
    let mut out = Vec::with_capacity(12);
    for i in 0..8usize {
        for k in 0..3 {
            if i >> k & 1 == 0 {
                out.push((corner(i), corner(i | 1 << k)));
            }
        }
    }
    out
}

impl ViewerApp {
    pub(super) fn clip_controls(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Clip boxes")
            .default_open(false)
            .show(ui, |ui| {
                let clips = &mut self.settings.filter.clips;
                let full = clips.len() >= ClipBox::MAX;
                if ui
                    .add_enabled(!full, egui::Button::new("Add box at the target"))
                    .clicked()
                {
                    // Around the point looked at: a sixth of the scene across, all its height.
                    let ds = self.renderer.dataset();
                    let t = self.camera.target.as_dvec3() + ds.anchor();
                    let b = &ds.metadata().bounds;
                    let half = ((b.max[0] - b.min[0]).max(b.max[1] - b.min[1]) / 12.0).max(1e-3);
                    clips.push(ClipBox {
                        min: [t.x - half, t.y - half, b.min[2]],
                        max: [t.x + half, t.y + half, b.max[2]],
                        outside: false,
                    });
                }
                ui.label(egui::RichText::new("drag the handles in the scene").small());
                let mut remove = None;
                for (i, c) in clips.iter_mut().enumerate() {
                    ui.horizontal(|ui| {
                        ui.label(format!("box {}", i + 1));
                        ui.checkbox(&mut c.outside, "hide inside");
                        if ui.small_button("✕").clicked() {
                            remove = Some(i);
                        }
                    });
                    for (name, k) in [("x", 0), ("y", 1), ("z", 2)] {
                        ui.horizontal(|ui| {
                            let span = (c.max[k] - c.min[k]).abs().max(1.0);
                            let speed = span / 200.0;
                            ui.label(name);
                            let hi = c.max[k];
                            ui.add(
                                egui::DragValue::new(&mut c.min[k])
                                    .speed(speed)
                                    .range(f64::MIN..=hi),
                            );
                            let lo = c.min[k];
                            ui.add(
                                egui::DragValue::new(&mut c.max[k])
                                    .speed(speed)
                                    .range(lo..=f64::MAX),
                            );
                        });
                    }
                }
                if let Some(i) = remove {
                    clips.remove(i);
                }
            });
    }

    fn clip_projector(&self, size: (u32, u32)) -> ScreenProjector {
        ScreenProjector::new(self.renderer.dataset(), &self.camera, size.0, size.1)
    }

    /// Takes a drag that starts on a clip box handle; returns whether the drag is the handle's
    /// (the camera then stays).
    pub(super) fn drag_clip(&mut self, response: &egui::Response, rect: egui::Rect) -> bool {
        let Some(size) = self.renderer.output().map(|o| (o.width(), o.height())) else {
            return false;
        };
        let proj = self.clip_projector(size);
        let scale = [
            size.0 as f32 / rect.width().max(1.0),
            size.1 as f32 / rect.height().max(1.0),
        ];
        if response.drag_started_by(egui::PointerButton::Primary)
            && let Some(press) = response.interact_pointer_pos()
        {
            let at = [
                (press.x - rect.min.x) * scale[0],
                (press.y - rect.min.y) * scale[1],
            ];
            self.clip_drag = handles(&proj, &self.settings.filter.clips)
                .into_iter()
                .map(|(p, h)| ((p[0] - at[0]).hypot(p[1] - at[1]), h))
                .filter(|(d, _)| *d <= GRAB_PX * scale[0])
                // On a tie (a face seen end on lies on the centre) the face wins: the centre
                // stays reachable from the other views, the face from none.
                .min_by(|a, b| {
                    let centre = |h: &Handle| matches!(h, Handle::Centre { .. });
                    a.0.total_cmp(&b.0).then(centre(&a.1).cmp(&centre(&b.1)))
                })
                .map(|(_, h)| h);
        }
        let Some(handle) = self.clip_drag else {
            return false;
        };
        if response.dragged() {
            let d = response.drag_delta();
            let drag = [d.x * scale[0], d.y * scale[1]];
            drag_handle(&proj, &mut self.settings.filter.clips, handle, drag);
        }
        if response.drag_stopped() || !response.dragged() {
            self.clip_drag = None;
        }
        true
    }

    /// Paints the clip boxes' edges and handles over the scene.
    pub(super) fn paint_clips(&self, painter: &egui::Painter, rect: egui::Rect, size: (u32, u32)) {
        let clips = &self.settings.filter.clips;
        if clips.is_empty() {
            return;
        }
        let proj = self.clip_projector(size);
        let to_screen = |[x, y]: [f32; 2]| {
            egui::pos2(
                rect.min.x + x / proj.width * rect.width(),
                rect.min.y + y / proj.height * rect.height(),
            )
        };
        for b in clips {
            for (a, c) in edges(b) {
                if let Some((p, q)) = proj.segment(a, c) {
                    painter
                        .line_segment([to_screen(p), to_screen(q)], egui::Stroke::new(1.5, COLOUR));
                }
            }
        }
        for (p, h) in handles(&proj, clips) {
            let grabbed = self.clip_drag == Some(h);
            let r = if matches!(h, Handle::Centre { .. }) {
                6.0
            } else {
                4.5
            };
            let fill = if grabbed {
                egui::Color32::WHITE
            } else {
                COLOUR
            };
            painter.circle(
                to_screen(p),
                r,
                fill,
                egui::Stroke::new(1.0, egui::Color32::BLACK),
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Camera;

    #[test]
    fn a_handle_follows_the_drag_along_its_axis() {
        let anchor = DVec3::new(1000.0, 2000.0, 0.0);
        let cam = Camera::parse(
            "eye=1000,1970,40;target=1000,2000,0;fov=50",
            anchor,
            Camera::fit(glam::Vec3::splat(-1.0), glam::Vec3::splat(1.0), 0.8, 1.0),
        )
        .expect("camera");
        let proj = ScreenProjector::from_view(&cam, anchor, 400, 300, 1.0, 500.0);
        let mut boxes = vec![ClipBox {
            min: [990.0, 1990.0, -5.0],
            max: [1010.0, 2010.0, 5.0],
            outside: false,
        }];
        let all = handles(&proj, &boxes);
        assert_eq!(all.len(), 7);
        // The +x face, dragged by the image of 2 units along x, moves 2 units.
        let face = Handle::Face {
            index: 0,
            axis: 0,
            max: true,
        };
        let at = all.iter().find(|(_, h)| *h == face).expect("handle").0;
        let two = proj.to_pixel([1012.0, 2000.0, 0.0]).expect("in front");
        drag_handle(&proj, &mut boxes, face, [two[0] - at[0], two[1] - at[1]]);
        assert!((boxes[0].max[0] - 1012.0).abs() < 0.05, "{:?}", boxes[0]);
        assert_eq!(boxes[0].min, [990.0, 1990.0, -5.0]);
        // A face never passes the opposite one.
        let low = Handle::Face {
            index: 0,
            axis: 0,
            max: false,
        };
        drag_handle(&proj, &mut boxes, low, [1e4, 0.0]);
        assert!(boxes[0].min[0] <= boxes[0].max[0]);
        // The centre moves the box across the ground: x and y, both ends, height kept.
        let mut b = vec![ClipBox {
            min: [990.0, 1990.0, -5.0],
            max: [1010.0, 2010.0, 5.0],
            outside: false,
        }];
        let c = proj.to_pixel([1000.0, 2000.0, 0.0]).expect("centre");
        let to = proj.to_pixel([1003.0, 2004.0, 0.0]).expect("target");
        drag_handle(
            &proj,
            &mut b,
            Handle::Centre { index: 0 },
            [to[0] - c[0], to[1] - c[1]],
        );
        let moved = [
            (b[0].min[0] + b[0].max[0]) / 2.0,
            (b[0].min[1] + b[0].max[1]) / 2.0,
        ];
        assert!(
            (moved[0] - 1003.0).abs() < 0.05 && (moved[1] - 2004.0).abs() < 0.05,
            "{moved:?}"
        );
        assert_eq!((b[0].min[2], b[0].max[2]), (-5.0, 5.0));
        assert_eq!(edges(&b[0]).len(), 12);
    }
}
