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

/// Bits stored per voxel in a voxmap. Two bits hold only the [`Voxel`] kind (the paper's format);
/// four and eight bits also hold a distance layer (see [`LayeredVoxel`]), giving a deeper, smoother
/// force field.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum VoxelWidth {
    /// 2 bits: kind only, layer always 0.
    #[default]
    Two,
    /// 4 bits: kind and a small distance layer.
    Four,
    /// 8 bits: kind and a larger distance layer.
    Eight,
}

impl VoxelWidth {
    /// All widths, narrowest first.
    pub const ALL: [VoxelWidth; 3] = [VoxelWidth::Two, VoxelWidth::Four, VoxelWidth::Eight];

    /// Bits per voxel: 2, 4 or 8.
    pub fn bits(self) -> u32 {
        match self {
            VoxelWidth::Two => 2,
            VoxelWidth::Four => 4,
            VoxelWidth::Eight => 8,
        }
    }

    /// The width with `bits` bits per voxel, if it is 2, 4 or 8.
    pub fn from_bits(bits: u32) -> Option<VoxelWidth> {
        match bits {
            2 => Some(VoxelWidth::Two),
            4 => Some(VoxelWidth::Four),
            8 => Some(VoxelWidth::Eight),
            _ => None,
        }
    }
}

/// A voxel's kind and distance layer.
///
/// Surface: layer 0 is the outermost force layer (the 2-bit Surface), layer ℓ lies ℓ voxel layers
/// deeper (26-neighbour distance from the outside). Proximity: layer 0 is the 2-bit Proximity
/// (adjacent to Surface layer 0), ℓ is ℓ layers farther out. Interior: deeper than every Surface
/// layer; Free: beyond every Proximity layer. Layer is always 0 in a 2-bit map (and for Interior and
/// Free in any map).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LayeredVoxel {
    /// The voxel's kind.
    pub kind: Voxel,
    /// Distance layer in voxels (0 = the 2-bit layer of that kind).
    pub layer: u8,
}
