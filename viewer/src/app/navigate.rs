//! The scene's mouse and keys: orbit, pan, zoom, fly, reset; a click picks the stored point
//! under the cursor (feeding the measuring tool or the profile line being drawn), a double
//! click centres the view on it.

use super::ViewerApp;
use eframe::egui;

impl ViewerApp {
    pub(super) fn navigate(&mut self, ui: &egui::Ui, response: &egui::Response, rect: egui::Rect) {
        let size = rect.size();
        // A drag that starts on a clip box handle moves the handle, not the camera.
        if self.drag_clip(response, rect) {
            // The handle took the drag.
        } else if response.dragged_by(egui::PointerButton::Primary)
            && !ui.input(|i| i.modifiers.shift)
        {
            let d = response.drag_delta();
            self.camera.orbit(d.x / size.x * 4.0, d.y / size.y * 3.0);
        } else if response.dragged_by(egui::PointerButton::Secondary)
            || response.dragged_by(egui::PointerButton::Middle)
            || response.dragged_by(egui::PointerButton::Primary)
        {
            let d = response.drag_delta();
            self.camera.pan(d.x / size.y, d.y / size.y);
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                self.camera.zoom((-scroll * 0.002).exp());
            }
        }
        // The second click of a double click focuses; it adds no second vertex.
        if response.clicked()
            && !response.double_clicked()
            && let Some(pos) = response.interact_pointer_pos()
        {
            self.pick(pos, rect);
        }
        if response.double_clicked()
            && let Some(pos) = response.interact_pointer_pos()
        {
            self.focus(pos, rect);
        }
        let dt = ui.input(|i| i.stable_dt).min(0.1);
        let fast = if ui.input(|i| i.modifiers.shift) {
            4.0
        } else {
            1.0
        };
        let step = self.scene_size * 0.25 * dt * fast;
        let keys = ui.input(|i| {
            let k = |key| if i.key_down(key) { 1.0 } else { 0.0 };
            (
                k(egui::Key::W) - k(egui::Key::S),
                k(egui::Key::D) - k(egui::Key::A),
                k(egui::Key::E) - k(egui::Key::Q),
                i.key_pressed(egui::Key::R),
            )
        });
        if ui.ctx().egui_wants_keyboard_input() {
            return;
        }
        if keys.0 != 0.0 || keys.1 != 0.0 || keys.2 != 0.0 {
            self.camera.fly(keys.0 * step, keys.1 * step, keys.2 * step);
            ui.ctx().request_repaint();
        }
        if keys.3 {
            self.camera = self.home;
        }
    }

    /// The image pixel under a window position (the image may be smaller than the window).
    fn image_pixel(&self, pos: egui::Pos2, rect: egui::Rect) -> Option<(u32, u32)> {
        let output = self.renderer.output()?;
        let (w, h) = (output.width(), output.height());
        let x = (pos.x - rect.min.x) / rect.width().max(1.0) * w as f32;
        let y = (pos.y - rect.min.y) / rect.height().max(1.0) * h as f32;
        (x >= 0.0 && y >= 0.0 && x < w as f32 && y < h as f32).then_some((x as u32, y as u32))
    }

    /// Reads the stored point under a click for the panel.
    fn pick(&mut self, pos: egui::Pos2, rect: egui::Rect) {
        let Some((x, y)) = self.image_pixel(pos, rect) else {
            return;
        };
        self.picked = match self.renderer.pick(x, y, 8) {
            Ok(Some(p)) => {
                if self.profiling.drawing {
                    self.profiling.line.push(p.position);
                } else {
                    self.measuring.add(&p);
                }
                Some(Ok(p))
            }
            Ok(None) => None,
            Err(e) => Some(Err(e.to_string())),
        };
    }

    /// Centres the view on the point under the cursor (the nearest drawn pixel within 8).
    fn focus(&mut self, pos: egui::Pos2, rect: egui::Rect) {
        let Ok(depths) = self.renderer.read_depths() else {
            return;
        };
        let Some(output) = self.renderer.output() else {
            return;
        };
        let (w, h) = (output.width(), output.height());
        // The image may be smaller than the window (the adapter's limits): scale to it.
        let px = ((pos.x - rect.min.x) / rect.width().max(1.0) * w as f32) as i32;
        let py = ((pos.y - rect.min.y) / rect.height().max(1.0) * h as f32) as i32;
        let mut best: Option<(i32, i32, f32)> = None;
        for dy in -8..=8 {
            for dx in -8..=8 {
                let (x, y) = (px + dx, py + dy);
                if x < 0 || y < 0 || x >= w as i32 || y >= h as i32 {
                    continue;
                }
                if let Some(Some(d)) = depths.get((y as u32 * w + x as u32) as usize).copied()
                    && best
                        .is_none_or(|b| dx * dx + dy * dy < (b.0 - px).pow(2) + (b.1 - py).pow(2))
                {
                    best = Some((x, y, d));
                }
            }
        }
        let Some((x, y, depth)) = best else { return };
        let view = self.camera.view();
        let aspect = w as f32 / h as f32;
        let inv = (self.camera.projection(aspect, 0.1, 10.0) * view).inverse();
        let ndc = glam::Vec2::new(
            (x as f32 + 0.5) / w as f32 * 2.0 - 1.0,
            1.0 - (y as f32 + 0.5) / h as f32 * 2.0,
        );
        let far = inv.project_point3(ndc.extend(1.0));
        let dir = (far - self.camera.eye).normalize_or_zero();
        let forward = self.camera.forward();
        let point = self.camera.eye + dir * (depth / dir.dot(forward).max(1e-3));
        let offset = (self.camera.eye - point) * 0.5;
        self.camera.target = point;
        self.camera.eye = point + offset;
    }
}
