use std::fmt;

/// A node's place in the octree: its level (root = 0) and its integer cell index at that level.
///
/// Child `i` (octant, 0..8) of a node has index `2 * parent + ((i >> 2) & 1, (i >> 1) & 1, i & 1)`
/// in (x, y, z). The name is `r` followed by the octant digits from the root down ("r", "r0", "r07").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct NodeKey {
    pub level: u8,
    pub x: u32,
    pub y: u32,
    pub z: u32,
}

impl NodeKey {
    pub const ROOT: NodeKey = NodeKey {
        level: 0,
        x: 0,
        y: 0,
        z: 0,
    };

    pub fn child(&self, octant: u8) -> NodeKey {
        NodeKey {
            level: self.level + 1,
            x: (self.x << 1) | ((octant as u32 >> 2) & 1),
            y: (self.y << 1) | ((octant as u32 >> 1) & 1),
            z: (self.z << 1) | (octant as u32 & 1),
        }
    }

    pub fn parent(&self) -> Option<NodeKey> {
        (self.level > 0).then(|| NodeKey {
            level: self.level - 1,
            x: self.x >> 1,
            y: self.y >> 1,
            z: self.z >> 1,
        })
    }

    /// The octant of this node inside its parent.
    pub fn octant(&self) -> u8 {
        (((self.x & 1) << 2) | ((self.y & 1) << 1) | (self.z & 1)) as u8
    }

    /// Integer-coordinate minimum corner and edge length of this node inside a cube of
    /// `2^cube_bits` integer units starting at `cube_min`.
    pub fn int_bounds(&self, cube_min: [i64; 3], cube_bits: u32) -> ([i64; 3], i64) {
        let edge = 1i64 << (cube_bits - self.level as u32);
        (
            [
                cube_min[0] + self.x as i64 * edge,
                cube_min[1] + self.y as i64 * edge,
                cube_min[2] + self.z as i64 * edge,
            ],
            edge,
        )
    }

    pub fn name(&self) -> String {
        let mut s = String::with_capacity(1 + self.level as usize);
        s.push('r');
        for l in (0..self.level).rev() {
            let o = (((self.x >> l) & 1) << 2) | (((self.y >> l) & 1) << 1) | ((self.z >> l) & 1);
            s.push(char::from(b'0' + o as u8));
        }
        s
    }

    /// Parses a name made by [`NodeKey::name`].
    pub fn from_name(name: &str) -> Option<NodeKey> {
        let digits = name.strip_prefix('r')?;
        let mut key = NodeKey::ROOT;
        for c in digits.bytes() {
            if !(b'0'..=b'7').contains(&c) || key.level >= 31 {
                return None;
            }
            key = key.child(c - b'0');
        }
        Some(key)
    }
}

impl fmt::Display for NodeKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_children_nest() {
        let k = NodeKey::ROOT.child(0).child(7).child(3);
        assert_eq!(k.name(), "r073");
        assert_eq!(NodeKey::from_name("r073"), Some(k));
        assert_eq!(
            k.parent().and_then(|p| p.parent()),
            Some(NodeKey::ROOT.child(0))
        );
        assert_eq!(k.octant(), 3);
        assert_eq!(NodeKey::from_name("r8"), None);
        let (min, edge) = k.int_bounds([10, 20, 30], 10);
        assert_eq!(edge, 128);
        // r0 -> (0,0,0); r07 -> (1,1,1); r073 -> (2,3,3)
        assert_eq!(min, [10 + 2 * 128, 20 + 3 * 128, 30 + 3 * 128]);
    }
}
