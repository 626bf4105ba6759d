//! The forward program's output channels: the contract between a compiled graph and whoever
//! reads its kernel's columns (baking, the renderer's materials, the fit).
//!
//! A forward program has exactly [`Channel::COUNT`] outputs, output `k` being
//! `Channel::ALL[k]` and named [`Channel::name`]. Readers index columns with
//! [`Channel::index`], never with bare numbers.

use std::fmt;

/// One scalar output of a forward program, in output order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Channel {
    AlbedoR,
    AlbedoG,
    AlbedoB,
    Roughness,
    NormalX,
    NormalY,
    NormalZ,
    /// Height in tile units; 0 for graphs that give a `normal` directly.
    Height,
    /// 0 unless the graph sets it.
    Metallic,
}

impl Channel {
    /// How many channels a forward program outputs.
    pub const COUNT: usize = 9;

    /// Every channel, in output order: `ALL[c.index()] == c`.
    pub const ALL: [Channel; Channel::COUNT] = [
        Channel::AlbedoR,
        Channel::AlbedoG,
        Channel::AlbedoB,
        Channel::Roughness,
        Channel::NormalX,
        Channel::NormalY,
        Channel::NormalZ,
        Channel::Height,
        Channel::Metallic,
    ];

    /// Linear albedo, red, green, blue.
    pub const ALBEDO: [Channel; 3] = [Channel::AlbedoR, Channel::AlbedoG, Channel::AlbedoB];

    /// Unit tangent-space normal, x, y, z (OpenGL convention, +z out of the surface).
    pub const NORMAL: [Channel; 3] = [Channel::NormalX, Channel::NormalY, Channel::NormalZ];

    /// The output (and kernel column) index of this channel.
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The output's name in IR programs and dumps (`albedo.r`, `roughness`, …).
    pub const fn name(self) -> &'static str {
        match self {
            Channel::AlbedoR => "albedo.r",
            Channel::AlbedoG => "albedo.g",
            Channel::AlbedoB => "albedo.b",
            Channel::Roughness => "roughness",
            Channel::NormalX => "normal.x",
            Channel::NormalY => "normal.y",
            Channel::NormalZ => "normal.z",
            Channel::Height => "height",
            Channel::Metallic => "metallic",
        }
    }

    /// The channel with this output name.
    pub fn from_name(name: &str) -> Option<Channel> {
        Channel::ALL.into_iter().find(|c| c.name() == name)
    }
}

impl fmt::Display for Channel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::Channel;

    #[test]
    fn order_index_and_names_agree() {
        for (k, c) in Channel::ALL.into_iter().enumerate() {
            assert_eq!(c.index(), k);
            assert_eq!(Channel::from_name(c.name()), Some(c));
        }
        let names: Vec<_> = Channel::ALL.iter().map(|c| c.name()).collect();
        assert_eq!(
            names,
            ["albedo.r", "albedo.g", "albedo.b", "roughness", "normal.x", "normal.y", "normal.z", "height", "metallic"]
        );
        assert_eq!(Channel::from_name("albedo"), None);
    }
}
