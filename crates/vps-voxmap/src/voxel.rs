//! The four 2-bit voxel kinds (docs/architecture.md#voxmaps-and-point-shells).

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

    /// Merge precedence of docs/architecture.md#voxmaps-and-point-shells: Interior > Surface > Proximity > Free.
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

/// Stored codes of [`LayeredVoxel`]s, per width:
///
/// | width | Free | Interior | Surface layers | Proximity layers | reserved (invalid) |
/// |---|---|---|---|---|---|
/// | 2 | 0 | 1 | 2 (layer 0) | 3 (layer 0) | none |
/// | 4 | 0 | 1 | 2..=8 (layers 0..=6) | 9..=14 (layers 0..=5) | 15 |
/// | 8 | 0 | 1 | 2..=65 (layers 0..=63) | 66..=129 (layers 0..=63) | 130..=255 |
///
/// The 2-bit code is the [`Voxel`] value, so 2-bit maps are unchanged. Reserved codes exist so a
/// corrupt wide map is detectable; readers reject them.
impl VoxelWidth {
    /// log2 of [`VoxelWidth::bits`]: 1, 2 or 3.
    pub fn bits_log2(self) -> u32 {
        self.bits().trailing_zeros()
    }

    /// Number of Surface layers a code can hold (layers `0..n`): 1, 7 or 64.
    pub fn surface_layers(self) -> u8 {
        match self {
            VoxelWidth::Two => 1,
            VoxelWidth::Four => 7,
            VoxelWidth::Eight => 64,
        }
    }

    /// Number of Proximity layers a code can hold (layers `0..n`): 1, 6 or 64.
    pub fn proximity_layers(self) -> u8 {
        match self {
            VoxelWidth::Two => 1,
            VoxelWidth::Four => 6,
            VoxelWidth::Eight => 64,
        }
    }

    /// The first code of Proximity layer 0.
    fn proximity_base(self) -> u8 {
        2 + self.surface_layers()
    }

    /// One past the largest valid code.
    pub fn code_limit(self) -> u16 {
        self.proximity_base() as u16 + self.proximity_layers() as u16
    }

    /// True when `code` is a valid stored value of this width.
    #[inline]
    pub fn is_valid_code(self, code: u8) -> bool {
        (code as u16) < self.code_limit()
    }

    /// The stored code of `v`, or `None` when its layer does not fit this width (or it gives a layer
    /// to Free or Interior).
    pub fn encode(self, v: LayeredVoxel) -> Option<u8> {
        let fits = |n: u8| v.layer < n;
        match v.kind {
            Voxel::Free | Voxel::Interior => (v.layer == 0).then_some(v.kind as u8),
            Voxel::Surface => fits(self.surface_layers()).then_some(2 + v.layer),
            Voxel::Proximity => {
                fits(self.proximity_layers()).then(|| self.proximity_base() + v.layer)
            }
        }
    }

    /// The voxel stored as `code`, or `None` for a reserved code.
    #[inline]
    pub fn decode(self, code: u8) -> Option<LayeredVoxel> {
        let base = self.proximity_base();
        let (kind, layer) = match code {
            0 => (Voxel::Free, 0),
            1 => (Voxel::Interior, 0),
            c if c < base => (Voxel::Surface, c - 2),
            c if self.is_valid_code(c) => (Voxel::Proximity, c - base),
            _ => return None,
        };
        Some(LayeredVoxel { kind, layer })
    }

    /// The kind stored as a valid `code` (reserved codes read as Free).
    #[inline]
    pub fn kind_of(self, code: u8) -> Voxel {
        self.decode(code).map_or(Voxel::Free, |v| v.kind)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_round_trip_and_reserved_codes_are_invalid() {
        for w in VoxelWidth::ALL {
            let mut valid = 0;
            for code in 0..=255u8 {
                if (code as u32) >= 1 << w.bits() {
                    assert!(!w.is_valid_code(code), "{w:?} {code}");
                }
                match w.decode(code) {
                    Some(v) => {
                        valid += 1;
                        assert_eq!(w.encode(v), Some(code), "{w:?} {code}");
                        assert_eq!(w.kind_of(code), v.kind);
                    }
                    None => assert!(!w.is_valid_code(code)),
                }
            }
            assert_eq!(valid, w.code_limit());
            assert_eq!(
                valid,
                2 + w.surface_layers() as u16 + w.proximity_layers() as u16
            );
            let too_deep = LayeredVoxel {
                kind: Voxel::Surface,
                layer: w.surface_layers(),
            };
            assert_eq!(w.encode(too_deep), None);
        }
        for k in Voxel::ALL {
            let v = LayeredVoxel { kind: k, layer: 0 };
            assert_eq!(VoxelWidth::Two.encode(v), Some(k.bits()));
        }
        assert_eq!(VoxelWidth::Four.decode(15), None);
        assert_eq!(VoxelWidth::Eight.decode(130), None);
    }
}
