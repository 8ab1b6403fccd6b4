//! The six faces of the circumscribing cube, their frames, and which face a direction is on.

use std::fmt;
use std::str::FromStr;

use glam::DVec3;

use super::EcmError;

/// A cube face, numbered and oriented exactly as PROJ's `+proj=qsc` (see [`Face::proj_center`]).
///
/// Each face has a right-handed frame (x axis, y axis, centre) with x × y = centre:
///
/// | face | centre | x axis | y axis | PROJ centre |
/// |---|---|---|---|---|
/// | front 0 | +X | +Y (east) | +Z (north) | `+lat_0=0 +lon_0=0` |
/// | right 1 | +Y | −X | +Z | `+lat_0=0 +lon_0=90` |
/// | back 2 | −X | −Y | +Z | `+lat_0=0 +lon_0=180` |
/// | left 3 | −Y | +X | +Z | `+lat_0=0 +lon_0=-90` |
/// | top 4 | +Z | +Y | −X | `+lat_0=90` |
/// | bottom 5 | −Z | +Y | +X | `+lat_0=-90` |
///
/// X, Y, Z are ECEF axes (X through lat 0 lon 0, Z north).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum Face {
    /// Centred on latitude 0, longitude 0.
    Front = 0,
    /// Centred on latitude 0, longitude 90° E.
    Right = 1,
    /// Centred on latitude 0, longitude 180°.
    Back = 2,
    /// Centred on latitude 0, longitude 90° W.
    Left = 3,
    /// Centred on the north pole.
    Top = 4,
    /// Centred on the south pole.
    Bottom = 5,
}

/// One of the four edges of a face, in the face's own frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Edge {
    /// x = +1.
    East,
    /// y = +1.
    North,
    /// x = −1.
    West,
    /// y = −1.
    South,
}

impl Edge {
    /// All four edges, counter-clockwise from east.
    pub const ALL: [Edge; 4] = [Edge::East, Edge::North, Edge::West, Edge::South];

    /// The unit step (dx, dy) that crosses this edge.
    pub fn step(self) -> (i64, i64) {
        match self {
            Edge::East => (1, 0),
            Edge::North => (0, 1),
            Edge::West => (-1, 0),
            Edge::South => (0, -1),
        }
    }
}

impl Face {
    /// All faces in PROJ's order.
    pub const ALL: [Face; 6] = [Face::Front, Face::Right, Face::Back, Face::Left, Face::Top, Face::Bottom];

    /// The face with PROJ's number 0–5.
    pub fn from_index(index: usize) -> Option<Face> {
        Face::ALL.get(index).copied()
    }

    /// PROJ's face number 0–5.
    pub fn index(self) -> usize {
        self as usize
    }

    /// Lower-case name: front, right, back, left, top, bottom.
    pub fn name(self) -> &'static str {
        match self {
            Face::Front => "front",
            Face::Right => "right",
            Face::Back => "back",
            Face::Left => "left",
            Face::Top => "top",
            Face::Bottom => "bottom",
        }
    }

    /// The PROJ projection centre `+lat_0=… +lon_0=…` that selects this face in `+proj=qsc`.
    pub fn proj_center(self) -> &'static str {
        match self {
            Face::Front => "+lat_0=0 +lon_0=0",
            Face::Right => "+lat_0=0 +lon_0=90",
            Face::Back => "+lat_0=0 +lon_0=180",
            Face::Left => "+lat_0=0 +lon_0=-90",
            Face::Top => "+lat_0=90 +lon_0=0",
            Face::Bottom => "+lat_0=-90 +lon_0=0",
        }
    }

    /// Unit vector from the centre of the body to the centre of the face, ECEF axes.
    pub fn center(self) -> DVec3 {
        match self {
            Face::Front => DVec3::X,
            Face::Right => DVec3::Y,
            Face::Back => DVec3::NEG_X,
            Face::Left => DVec3::NEG_Y,
            Face::Top => DVec3::Z,
            Face::Bottom => DVec3::NEG_Z,
        }
    }

    /// Unit vector of the face's x axis, ECEF axes.
    pub fn x_axis(self) -> DVec3 {
        match self {
            Face::Front => DVec3::Y,
            Face::Right => DVec3::NEG_X,
            Face::Back => DVec3::NEG_Y,
            Face::Left => DVec3::X,
            Face::Top | Face::Bottom => DVec3::Y,
        }
    }

    /// Unit vector of the face's y axis, ECEF axes.
    pub fn y_axis(self) -> DVec3 {
        match self {
            Face::Top => DVec3::NEG_X,
            Face::Bottom => DVec3::X,
            _ => DVec3::Z,
        }
    }

    /// The direction `d` (ECEF axes) in this face's frame: (along x, along y, along centre).
    /// Exact: every component is a signed copy of one of `d`'s.
    pub fn local_from_ecef(self, d: DVec3) -> DVec3 {
        match self {
            Face::Front => DVec3::new(d.y, d.z, d.x),
            Face::Right => DVec3::new(-d.x, d.z, d.y),
            Face::Back => DVec3::new(-d.y, d.z, -d.x),
            Face::Left => DVec3::new(d.x, d.z, -d.y),
            Face::Top => DVec3::new(d.y, -d.x, d.z),
            Face::Bottom => DVec3::new(d.y, d.x, -d.z),
        }
    }

    /// Inverse of [`Face::local_from_ecef`].
    pub fn ecef_from_local(self, l: DVec3) -> DVec3 {
        match self {
            Face::Front => DVec3::new(l.z, l.x, l.y),
            Face::Right => DVec3::new(-l.x, l.z, l.y),
            Face::Back => DVec3::new(-l.z, -l.x, l.y),
            Face::Left => DVec3::new(l.x, -l.z, l.y),
            Face::Top => DVec3::new(-l.y, l.x, l.z),
            Face::Bottom => DVec3::new(l.y, l.x, -l.z),
        }
    }

    /// The face a direction from the centre (ECEF axes, any length > 0) falls on: the one whose
    /// centre axis has the largest absolute component.
    ///
    /// Ties, which happen only on face edges and corners, are broken deterministically: top and
    /// bottom win over the equatorial faces, and front and back win over right and left. A
    /// point on an edge therefore belongs to exactly one face, and the cube corners belong to top
    /// and bottom. The zero vector is put on top.
    pub fn of_direction(d: DVec3) -> Face {
        let (ax, ay, az) = (d.x.abs(), d.y.abs(), d.z.abs());
        if az >= ax && az >= ay {
            if d.z >= 0.0 { Face::Top } else { Face::Bottom }
        } else if ax >= ay {
            if d.x >= 0.0 { Face::Front } else { Face::Back }
        } else if d.y >= 0.0 {
            Face::Right
        } else {
            Face::Left
        }
    }
}

impl fmt::Display for Face {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Face {
    type Err = EcmError;

    /// Parses a face name (any case) or PROJ's number 0–5.
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let t = text.trim().to_ascii_lowercase();
        if let Ok(index) = t.parse::<usize>() {
            return Face::from_index(index).ok_or_else(|| EcmError::UnknownFace(text.to_string()));
        }
        Face::ALL.into_iter().find(|face| face.name() == t).ok_or_else(|| EcmError::UnknownFace(text.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_right_handed_and_invert() {
        for face in Face::ALL {
            assert_eq!(face.x_axis().cross(face.y_axis()), face.center(), "{face}");
            let d = DVec3::new(0.3, -0.5, 0.8);
            let local = face.local_from_ecef(d);
            assert_eq!(local.x, d.dot(face.x_axis()));
            assert_eq!(local.y, d.dot(face.y_axis()));
            assert_eq!(local.z, d.dot(face.center()));
            assert_eq!(face.ecef_from_local(local), d);
            assert_eq!(Face::of_direction(face.center()), face);
        }
    }

    #[test]
    fn ties_are_deterministic() {
        assert_eq!(Face::of_direction(DVec3::new(1.0, 1.0, 1.0)), Face::Top);
        assert_eq!(Face::of_direction(DVec3::new(1.0, -1.0, -1.0)), Face::Bottom);
        assert_eq!(Face::of_direction(DVec3::new(1.0, 1.0, 0.0)), Face::Front);
        assert_eq!(Face::of_direction(DVec3::new(-1.0, -1.0, 0.5)), Face::Back);
        assert_eq!(Face::of_direction(DVec3::new(0.0, -1.0, 0.5)), Face::Left);
        assert_eq!("Top".parse::<Face>().unwrap(), Face::Top);
        assert_eq!("2".parse::<Face>().unwrap(), Face::Back);
        assert!("6".parse::<Face>().is_err());
        assert!("side".parse::<Face>().is_err());
    }
}
