//! Height profiles: the stored points within a corridor around a horizontal polyline, as
//! distance along the line against height. Read from the dataset level by level, coarse to
//! fine, down to the profile's own level of detail (its spacing), not the view's, and only the
//! nodes the corridor crosses.

use crate::ViewerError;
use crate::dataset::StreamDataset;
use crate::lod::Tree;
use crate::pick::{attribute_values, exact_integers, to_decimals};
use std::io::Write;
use std::path::Path;
use strata_format::{NodeInfo, NodeKey, PageRef, RowLayout};

/// A polyline in the horizontal plane (dataset coordinates) and the width of the band around
/// it: a point belongs to the profile where it lies across a segment (its foot on the segment)
/// within half the width of it.
#[derive(Debug, Clone, PartialEq)]
pub struct Corridor {
    pub line: Vec<[f64; 2]>,
    pub width: f64,
}

/// Where a point lies in a corridor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Place {
    /// Distance along the polyline to the point's foot.
    pub along: f64,
    /// Signed distance from the line, positive to the left of its direction.
    pub offset: f64,
}

impl Corridor {
    /// Parses `X,Y;X,Y[;...]` with a width; the error names what is wrong.
    pub fn parse(line: &str, width: f64) -> Result<Corridor, ViewerError> {
        let fail = |what: &str| ViewerError::argument(line, what);
        let points = line
            .split(';')
            .map(str::trim)
            .filter(|p| !p.is_empty())
            .map(|p| {
                let (x, y) = p.split_once(',')?;
                let (x, y) = (x.trim().parse::<f64>().ok()?, y.trim().parse::<f64>().ok()?);
                (x.is_finite() && y.is_finite()).then_some([x, y])
            })
            .collect::<Option<Vec<_>>>()
            .ok_or_else(|| fail("a profile line is X,Y;X,Y;... in the dataset's coordinates"))?;
        let c = Corridor {
            line: points,
            width,
        };
        c.check().map_err(|what| fail(&what))?;
        Ok(c)
    }

    /// Why the corridor cannot be used, if it cannot.
    pub fn check(&self) -> Result<(), String> {
        if self.line.len() < 2 {
            return Err("a profile line needs at least two points".into());
        }
        if !(self.width.is_finite() && self.width > 0.0) {
            return Err(format!(
                "the profile width {} is not a finite distance above 0",
                strata_format::number(self.width)
            ));
        }
        let length = self.length();
        if length == 0.0 {
            return Err("the profile line has no length".into());
        }
        // Coordinates near f64's limit make every distance along the line infinite.
        if !length.is_finite() {
            return Err("the profile line is too long to measure along".into());
        }
        Ok(())
    }

    /// Length of the polyline.
    pub fn length(&self) -> f64 {
        self.line
            .windows(2)
            .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
            .sum()
    }

    /// Where `(x, y)` lies: across the segment nearest it, within half the width; `None`
    /// outside the corridor.
    pub fn place(&self, x: f64, y: f64) -> Option<Place> {
        let segments: Vec<usize> = (0..self.line.len().saturating_sub(1)).collect();
        self.place_among(x, y, &segments, &self.starts())
    }

    /// Distance along the polyline to the start of each segment.
    pub fn starts(&self) -> Vec<f64> {
        let mut before = 0.0;
        self.line
            .windows(2)
            .map(|w| {
                let at = before;
                before += (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]);
                at
            })
            .collect()
    }

    /// As [`Corridor::place`], trying only `segments` (in line order: the first of equally
    /// near ones wins), whose starts along the line are `starts` (`Corridor::starts`).
    pub fn place_among(&self, x: f64, y: f64, segments: &[usize], starts: &[f64]) -> Option<Place> {
        let half = self.width / 2.0;
        let mut best: Option<Place> = None;
        for &k in segments {
            let (a, b) = (self.line[k], self.line[k + 1]);
            let d = [b[0] - a[0], b[1] - a[1]];
            let len = d[0].hypot(d[1]);
            if len > 0.0 {
                let (ux, uy) = (d[0] / len, d[1] / len);
                let (px, py) = (x - a[0], y - a[1]);
                let t = px * ux + py * uy;
                let off = ux * py - uy * px;
                // A point on the end vertex or the band's edge lies on it to rounding: through
                // the unit vector, t there can come out a few ulps past the segment's length.
                let ulps = 8.0 * f64::EPSILON * (a[0].abs() + a[1].abs() + len + half);
                if (-ulps..=len + ulps).contains(&t)
                    && off.abs() <= half + ulps
                    && best.is_none_or(|b| off.abs() < b.offset.abs())
                {
                    best = Some(Place {
                        along: starts[k] + t.clamp(0.0, len),
                        offset: off,
                    });
                }
            }
        }
        best
    }

    /// The segments whose bands meet the rectangle `min`-`max`, in line order: a node's points
    /// need be tried against these alone (a line of thousands of vertices made every point try
    /// every segment). The rectangle is widened by a hair beyond the rounding `place_among`
    /// allows, so that no point it takes is left out.
    pub fn segments_meeting(&self, min: [f64; 2], max: [f64; 2]) -> Vec<usize> {
        let hair = |v: f64| 1e-9 * (v.abs() + self.width) + 1e-300;
        let min = [min[0] - hair(min[0]), min[1] - hair(min[1])];
        let max = [max[0] + hair(max[0]), max[1] + hair(max[1])];
        (0..self.line.len().saturating_sub(1))
            .filter(|&k| self.segment_meets(k, min, max))
            .collect()
    }

    /// Whether the rectangle `min`-`max` may hold a point of the corridor: it meets one
    /// segment's band.
    pub fn meets(&self, min: [f64; 2], max: [f64; 2]) -> bool {
        (0..self.line.len().saturating_sub(1)).any(|k| self.segment_meets(k, min, max))
    }

    /// Whether the rectangle `min`-`max` meets segment `k`'s band (separating axes of two
    /// rectangles).
    fn segment_meets(&self, k: usize, min: [f64; 2], max: [f64; 2]) -> bool {
        let half = self.width / 2.0;
        let centre = [(min[0] + max[0]) / 2.0, (min[1] + max[1]) / 2.0];
        let ext = [(max[0] - min[0]) / 2.0, (max[1] - min[1]) / 2.0];
        let (a, b) = (self.line[k], self.line[k + 1]);
        let d = [b[0] - a[0], b[1] - a[1]];
        let len = d[0].hypot(d[1]);
        if len == 0.0 {
            return false;
        }
        let u = [d[0] / len, d[1] / len];
        let n = [-u[1], u[0]];
        let mid = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0];
        let c = [mid[0] - centre[0], mid[1] - centre[1]];
        let (bu, bn) = (len / 2.0, half);
        // The box's axes.
        let on_x = c[0].abs() <= ext[0] + bu * u[0].abs() + bn * n[0].abs();
        let on_y = c[1].abs() <= ext[1] + bu * u[1].abs() + bn * n[1].abs();
        // The band's axes.
        let r = |v: [f64; 2]| ext[0] * v[0].abs() + ext[1] * v[1].abs();
        let on_u = (c[0] * u[0] + c[1] * u[1]).abs() <= bu + r(u);
        let on_n = (c[0] * n[0] + c[1] * n[1]).abs() <= bn + r(n);
        on_x && on_y && on_u && on_n
    }
}

/// One point of a profile.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProfilePoint {
    pub place: Place,
    /// Real-world coordinates.
    pub position: [f64; 3],
}

/// The points of a corridor, with their stored rows (every attribute), in reading order.
#[derive(Debug, Clone)]
pub struct Profile {
    pub corridor: Corridor,
    pub points: Vec<ProfilePoint>,
    /// The points' rows in the dataset's row layout, one per point in order.
    pub rows: Vec<u8>,
    pub layout: RowLayout,
    /// The deepest level read, and its point spacing.
    pub level: u32,
    pub spacing: f64,
    /// Points read from the dataset (of the nodes the corridor crosses).
    pub points_read: u64,
    /// Whether the levels down to the asked spacing were all read (else the cap on points
    /// read stopped it).
    pub complete: bool,
    /// Decimals of the distance and offset columns: those of the finer horizontal scale and
    /// one more (at least 4), so that degrees (1e-7) keep theirs.
    pub decimals: usize,
}

/// How detailed a profile is read.
#[derive(Debug, Clone, Copy)]
pub struct ProfileDetail {
    /// Levels are read until their point spacing is at most this (0: every level).
    pub spacing: f64,
    /// A level is not started when it would take the points read past this.
    pub max_points_read: u64,
}

/// Decimals for the CSV's distance and offset at a dataset's `scale`: those of the finer
/// horizontal step and one more, at least 4 and at most 15.
pub fn csv_decimals(scale: [f64; 3]) -> usize {
    (1.0 - scale[0].min(scale[1]).log10())
        .ceil()
        .clamp(4.0, 15.0) as usize
}

/// Reads the profile of `corridor`, calling `on_level` with what there is after each level;
/// it stops after a level where `on_level` returns false (no one wants more).
pub fn extract(
    ds: &StreamDataset,
    corridor: &Corridor,
    detail: ProfileDetail,
    mut on_level: impl FnMut(&Profile) -> bool,
) -> Result<Profile, ViewerError> {
    corridor
        .check()
        .map_err(|what| ViewerError::argument(format!("{:?}", corridor.line), what))?;
    let m = ds.metadata();
    let layout = m.row_layout();
    let mut out = Profile {
        corridor: corridor.clone(),
        points: Vec::new(),
        rows: Vec::new(),
        layout: layout.clone(),
        level: 0,
        spacing: f64::INFINITY,
        points_read: 0,
        complete: true,
        decimals: csv_decimals(m.scale),
    };
    let mut tree = Tree::of(ds)?;
    let mut level: Vec<NodeInfo> = tree.node(NodeKey::ROOT).copied().into_iter().collect();
    let mut depth = 0u32;
    while !level.is_empty() {
        let cost: u64 = level.iter().map(|n| n.point_count as u64).sum();
        if depth > 0 && out.points_read + cost > detail.max_points_read {
            out.complete = false;
            break;
        }
        for info in &level {
            if info.point_count > 0 {
                read_node(ds, info, corridor, &mut out)?;
            }
        }
        out.level = depth;
        // The metadata's spacing, in doubles: a level's spacing given in decimals (as `info`
        // prints it) then asks for that level, where the single-precision node spacing could
        // come out a hair above it and read one level more.
        out.spacing = m.spacing / (1u64 << depth) as f64;
        if !on_level(&out) || out.spacing <= detail.spacing {
            break;
        }
        level = children(ds, &mut tree, &level, corridor)?;
        depth += 1;
    }
    Ok(out)
}

/// The real-world horizontal rectangle of node `key`'s cube.
fn node_rect(ds: &StreamDataset, key: NodeKey) -> ([f64; 2], [f64; 2]) {
    let m = ds.metadata();
    let (min, edge) = key.int_bounds(m.cube.min, m.cube.bits);
    let at = |i: usize, v: i64| m.offset[i] + m.scale[i] * v as f64;
    (
        [at(0, min[0]), at(1, min[1])],
        [at(0, min[0] + edge), at(1, min[1] + edge)],
    )
}

/// The children of `level` whose cubes the corridor crosses, loading hierarchy pages as needed.
fn children(
    ds: &StreamDataset,
    tree: &mut Tree,
    level: &[NodeInfo],
    corridor: &Corridor,
) -> Result<Vec<NodeInfo>, ViewerError> {
    let mut next = Vec::new();
    for info in level {
        if info.child_mask == 0 {
            continue;
        }
        // 1.1: the page below a proxy holds its children.
        if let Some(page) = tree.unloaded_page(info.key) {
            add_page(ds, tree, &page)?;
        }
        for octant in 0..8u8 {
            if info.child_mask & (1 << octant) == 0 {
                continue;
            }
            let child = info.key.child(octant);
            let (min, max) = node_rect(ds, child);
            if !corridor.meets(min, max) {
                continue;
            }
            // 1.0: a child proxy is known only from its own page.
            if tree.node(child).is_none()
                && let Some(page) = tree.unloaded_page(child)
            {
                add_page(ds, tree, &page)?;
            }
            if let Some(c) = tree.node(child) {
                next.push(*c);
            }
        }
    }
    Ok(next)
}

fn add_page(ds: &StreamDataset, tree: &mut Tree, page: &PageRef) -> Result<(), ViewerError> {
    let loaded = ds.load_page(page)?;
    tree.add_page(&loaded)
        .map_err(|what| ViewerError::source(ds.location(), what))
}

fn read_node(
    ds: &StreamDataset,
    info: &NodeInfo,
    corridor: &Corridor,
    out: &mut Profile,
) -> Result<(), ViewerError> {
    let m = ds.metadata();
    let cols = ds.read_columns(info)?;
    out.points_read += cols.count as u64;
    let rows = cols.to_rows(&out.layout);
    let stride = out.layout.stride;
    let (min, max) = node_rect(ds, info.key);
    let segments = corridor.segments_meeting(min, max);
    let starts = corridor.starts();
    for i in 0..cols.count {
        let int = cols.position(i);
        let p: [f64; 3] = std::array::from_fn(|k| {
            to_decimals(m.offset[k] + m.scale[k] * int[k] as f64, m.scale[k])
        });
        if let Some(place) = corridor.place_among(p[0], p[1], &segments, &starts) {
            out.points.push(ProfilePoint { place, position: p });
            out.rows
                .extend_from_slice(&rows[i * stride..(i + 1) * stride]);
        }
    }
    Ok(())
}

impl Profile {
    /// The columns of [`Profile::write_csv`]: distance, offset, x, y, z, then each attribute
    /// (`name` or `name_0`, `name_1`, ... for several components).
    pub fn csv_header(&self) -> Vec<String> {
        let mut h: Vec<String> = ["distance", "offset", "x", "y", "z"]
            .map(String::from)
            .to_vec();
        for a in &self.layout.attributes {
            if a.is_oct16() {
                h.extend(["x", "y", "z"].map(|c| format!("{}_{c}", a.name)));
            } else if a.count == 1 {
                h.push(a.name.clone());
            } else {
                h.extend((0..a.count).map(|c| format!("{}_{c}", a.name)));
            }
        }
        h
    }

    /// Writes the profile as CSV, through a temporary name.
    pub fn write_csv(&self, path: &Path) -> Result<(), ViewerError> {
        let fail = |e: std::io::Error| ViewerError::output(path, format!("cannot write ({e})"));
        let mut part = path.as_os_str().to_owned();
        part.push(".part");
        let part = std::path::PathBuf::from(part);
        let write = || -> std::io::Result<()> {
            let mut w = std::io::BufWriter::new(std::fs::File::create(&part)?);
            writeln!(w, "{}", self.csv_header().join(","))?;
            let stride = self.layout.stride;
            for (i, p) in self.points.iter().enumerate() {
                let [x, y, z] = p.position;
                let d = self.decimals;
                write!(
                    w,
                    "{:.d$},{:.d$},{x},{y},{z}",
                    p.place.along, p.place.offset
                )?;
                let row = &self.rows[i * stride..(i + 1) * stride];
                for (k, a) in self.layout.attributes.iter().enumerate() {
                    let at = self.layout.offsets[k];
                    let raw = &row[at..at + a.size()];
                    // A 64-bit integer whole; a double would round it.
                    match exact_integers(a, raw) {
                        Some(exact) => exact.iter().try_for_each(|v| write!(w, ",{v}"))?,
                        None => attribute_values(a, raw)
                            .iter()
                            .try_for_each(|v| write!(w, ",{v}"))?,
                    }
                }
                writeln!(w)?;
            }
            w.into_inner().map_err(|e| e.into_error())?.sync_all()
        };
        write()
            .and_then(|_| std::fs::rename(&part, path))
            .map_err(|e| {
                let _ = std::fs::remove_file(&part);
                fail(e)
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_on_the_end_vertex_and_on_the_band_edge_are_in_the_corridor() {
        // Through the unit vector, t at these end vertices came out past the segment's length.
        for (line, end) in [
            ("500001,4000001;500019,4000019", [500019.0, 4000019.0]),
            ("10,10;10.25,40", [10.25, 40.0]),
            ("5,5;25,25;5,25.5", [5.0, 25.5]),
        ] {
            let c = Corridor::parse(line, 1.0).expect("parses");
            let place = c.place(end[0], end[1]);
            let along = place.map(|p| p.along);
            assert_eq!(along, Some(c.length()), "{line}: {place:?}");
        }
        // A point half the width off a diagonal segment's middle is on the band's edge.
        let c = Corridor::parse("0,0;10,10", 2.0 * 2f64.sqrt()).expect("parses");
        assert!(c.place(4.0, 6.0).is_some());
        assert!(c.place(3.9, 6.1).is_none());
    }

    #[test]
    fn the_csv_keeps_fine_distances_and_writes_a_normal_as_a_vector() {
        let layout = RowLayout::new(vec![strata_format::Attribute::oct16_normal()]);
        let mut row = vec![0u8; 12];
        for c in strata_format::oct16_encode([0.0, 0.0, 1.0]) {
            row.extend(c.to_le_bytes());
        }
        let profile = Profile {
            corridor: Corridor::parse("11,48; 11.01,48.01", 0.002).expect("parses"),
            points: vec![ProfilePoint {
                place: Place {
                    along: 0.000_129_896,
                    offset: -0.000_081_1,
                },
                position: [11.0000001, 48.0000002, 300.0],
            }],
            rows: row,
            layout,
            level: 0,
            spacing: 0.0,
            points_read: 1,
            complete: true,
            // Degrees at 1e-7.
            decimals: csv_decimals([1e-7, 1e-7, 1e-3]),
        };
        assert_eq!(csv_decimals([0.01, 0.01, 0.01]), 4);
        assert_eq!(csv_decimals([0.0025, 0.001, 0.01]), 4);
        assert_eq!(csv_decimals([1e-5, 1e-5, 1e-3]), 6);
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("p.csv");
        profile.write_csv(&path).expect("writes");
        let text = std::fs::read_to_string(&path).expect("reads");
        let mut lines = text.lines();
        assert_eq!(
            lines.next(),
            Some("distance,offset,x,y,z,normal_x,normal_y,normal_z")
        );
        let row: Vec<&str> = lines.next().expect("a row").split(',').collect();
        assert_eq!(
            &row[..5],
            [
                "0.00012990",
                "-0.00008110",
                "11.0000001",
                "48.0000002",
                "300"
            ]
        );
        let n: Vec<f64> = row[5..]
            .iter()
            .map(|v| v.parse().expect("number"))
            .collect();
        assert!(
            (n[0].abs() + n[1].abs()) < 1e-4 && (n[2] - 1.0).abs() < 1e-6,
            "{n:?}"
        );
    }

    #[test]
    fn a_point_lies_across_the_nearest_segment_within_half_the_width() {
        let c = Corridor::parse("0,0; 10,0; 10,10", 2.0).expect("parses");
        assert_eq!(c.length(), 20.0);
        let p = c.place(4.0, 0.5).expect("inside");
        assert_eq!((p.along, p.offset), (4.0, 0.5));
        let p = c.place(10.5, 6.0).expect("on the second segment");
        assert_eq!((p.along, p.offset), (16.0, -0.5));
        assert!(c.place(4.0, 1.5).is_none());
        assert!(c.place(-0.5, 0.0).is_none(), "before the start");
        // Boxes: one across the line, one beside it, one far off.
        assert!(c.meets([3.0, -5.0], [4.0, 5.0]));
        assert!(c.meets([10.9, 4.0], [12.0, 5.0]));
        assert!(!c.meets([3.0, 1.5], [4.0, 5.0]));
        assert!(!c.meets([20.0, 20.0], [30.0, 30.0]));
        // A diagonal line: the box beside its end is not crossed, the one on it is.
        let d = Corridor::parse("0,0;10,10", 1.0).expect("parses");
        assert!(d.meets([4.0, 4.0], [5.0, 5.0]));
        assert!(!d.meets([0.0, 8.0], [2.0, 10.0]));
        for (bad, says) in [
            ("0,0", "at least two"),
            ("0,0;a,1", "X,Y;X,Y"),
            ("1,1;1,1", "no length"),
            ("-1e308,0;1e308,0", "too long"),
        ] {
            let e = Corridor::parse(bad, 1.0).expect_err(bad).to_string();
            assert!(e.contains(says), "{bad}: {e}");
        }
        assert!(Corridor::parse("0,0;1,1", 0.0).is_err());
    }

    #[test]
    fn a_cell_tries_only_the_segments_that_reach_it_and_places_every_point_alike() {
        // A winding line of 2,000 vertices over a 100 x 100 field, crossing itself.
        let line: Vec<String> = (0..=2000)
            .map(|i| {
                let t = i as f64 / 20.0;
                format!("{},{}", t, 50.0 + 40.0 * (t * 0.7).sin() * (t * 0.05).cos())
            })
            .collect();
        let c = Corridor::parse(&line.join(";"), 3.0).expect("parses");
        let starts = c.starts();
        let mut tried = 0;
        let mut placed = 0;
        // Cells of 12.5 x 12.5, and points on a grid finer than the band, edges included.
        for cx in 0..8 {
            for cy in 0..8 {
                let min = [cx as f64 * 12.5, cy as f64 * 12.5];
                let max = [min[0] + 12.5, min[1] + 12.5];
                let segments = c.segments_meeting(min, max);
                tried += segments.len();
                for i in 0..=25 {
                    for j in 0..=25 {
                        let (x, y) = (min[0] + i as f64 * 0.5, min[1] + j as f64 * 0.5);
                        let all = c.place(x, y);
                        assert_eq!(all, c.place_among(x, y, &segments, &starts), "{x},{y}");
                        placed += all.is_some() as usize;
                    }
                }
            }
        }
        assert!(placed > 1000, "{placed} points in the corridor");
        // Every cell tried every segment before.
        assert!(tried < 64 * 2000 / 8, "{tried} segment tries");
    }
}
