//! The four 2-bit voxel kinds (DESIGN §2).

/// A voxel's kind; the discriminant is the 2-bit stored value.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum Voxel {
    /// Only free space.
    Free = 0,
    /// Only interior of a static object.
    Interior = 1,
    /// The force layer.
    Surface = 2,
    /// A free-space 26-neighbour of a Surface voxel (pre-contact braking layer).
    Proximity = 3,
}

impl Voxel {
    /// All kinds in value order.
    pub const ALL: [Voxel; 4] = [
        Voxel::Free,
        Voxel::Interior,
        Voxel::Surface,
        Voxel::Proximity,
    ];

    /// The kind stored as `bits` (only the low two bits are read).
    #[inline(always)]
    pub fn from_bits(bits: u8) -> Voxel {
        match bits & 3 {
            0 => Voxel::Free,
            1 => Voxel::Interior,
            2 => Voxel::Surface,
            _ => Voxel::Proximity,
        }
    }

    /// The 2-bit stored value.
    #[inline(always)]
    pub fn bits(self) -> u8 {
        self as u8
    }

    /// Merge precedence of DESIGN §2: Interior > Surface > Proximity > Free.
    pub fn precedence(self) -> u8 {
        match self {
            Voxel::Free => 0,
            Voxel::Proximity => 1,
            Voxel::Surface => 2,
            Voxel::Interior => 3,
        }
    }

    /// The kind that wins when two objects claim the same voxel.
    pub fn merge(self, other: Voxel) -> Voxel {
        if other.precedence() > self.precedence() {
            other
        } else {
            self
        }
    }

    /// Lower-case name, as used in JSON output.
    pub fn name(self) -> &'static str {
        match self {
            Voxel::Free => "free",
            Voxel::Interior => "interior",
            Voxel::Surface => "surface",
            Voxel::Proximity => "proximity",
        }
    }
}
