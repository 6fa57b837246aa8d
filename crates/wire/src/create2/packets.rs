//! Sensor packets: sizes of the single packets 7-58 and the group packets,
//! and (device side) their bytes from a [`SensorState`].

use core::ops::RangeInclusive;

use heapless::Vec as HVec;

use super::STREAM_HEADER;

/// Data size in bytes of single sensor packet `id` (7..=58), `None` for group
/// packets and unknown ids.
pub fn packet_size(id: u8) -> Option<usize> {
    match id {
        7..=18 | 21 | 24 | 32 | 34..=38 | 45 | 52 | 53 | 58 => Some(1),
        19 | 20 | 22 | 23 | 25..=31 | 33 | 39..=44 | 46..=51 | 54..=57 => Some(2),
        _ => None,
    }
}

/// The single packets group packet `id` carries, in order; `None` for single
/// packets and unknown ids.
pub(crate) fn group_members(id: u8) -> Option<RangeInclusive<u8>> {
    match id {
        0 => Some(7..=26),
        1 => Some(7..=16),
        2 => Some(17..=20),
        3 => Some(21..=26),
        4 => Some(27..=34),
        5 => Some(35..=42),
        6 => Some(7..=42),
        100 => Some(7..=58),
        101 => Some(43..=58),
        106 => Some(46..=51),
        107 => Some(54..=58),
        _ => None,
    }
}

/// Data size of any packet, single or group; `None` for ids the
/// specification does not define.
pub fn response_size(id: u8) -> Option<usize> {
    match group_members(id) {
        Some(m) => m.map(packet_size).sum(),
        None => packet_size(id),
    }
}

/// Whether reading packet `id` (single or group) reads single packet `single`.
pub fn reads(id: u8, single: u8) -> bool {
    id == single || group_members(id).is_some_and(|m| m.contains(&single))
}

/// Everything the robot reports (device side), one field per single packet.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SensorState {
    /// Packet 7: bit 0 bump right, 1 bump left, 2 wheel drop right, 3 left.
    pub bumps_drops: u8,
    /// Packet 8: wall seen.
    pub wall: u8,
    /// Packets 9-12: cliff left, front left, front right, right.
    pub cliff: [u8; 4],
    /// Packet 13: virtual wall seen.
    pub virtual_wall: u8,
    /// Packet 14: wheel and brush overcurrents.
    pub overcurrents: u8,
    /// Packet 15: dirt detect level.
    pub dirt: u8,
    /// Packet 17: IR character received by the omni receiver (0 none).
    pub ir_omni: u8,
    /// Packet 18: buttons pressed.
    pub buttons: u8,
    /// Packet 19: distance since last read (mm).
    pub distance_mm: i16,
    /// Packet 20: angle since last read (degrees, counter-clockwise positive).
    pub angle_deg: i16,
    /// Packet 21: charging state (0 not charging).
    pub charging_state: u8,
    /// Packet 22: battery voltage (mV).
    pub voltage_mv: u16,
    /// Packet 23: battery current (mA, negative when discharging).
    pub current_ma: i16,
    /// Packet 24: battery temperature (°C).
    pub temperature_c: i8,
    /// Packet 25: battery charge (mAh).
    pub charge_mah: u16,
    /// Packet 26: battery capacity (mAh).
    pub capacity_mah: u16,
    /// Packet 27: wall signal strength.
    pub wall_signal: u16,
    /// Packets 28-31: cliff signals (left, front left, front right, right).
    pub cliff_signal: [u16; 4],
    /// Packet 34: charging sources available.
    pub charging_sources: u8,
    /// Packet 35: OI mode byte.
    pub oi_mode: u8,
    /// Packet 36: selected song.
    pub song_number: u8,
    /// Packet 37: a song is playing.
    pub song_playing: u8,
    /// Packet 38: number of packets in the stream.
    pub stream_packets: u8,
    /// Packet 39: requested velocity (mm/s).
    pub velocity: i16,
    /// Packet 40: requested radius (mm).
    pub radius: i16,
    /// Packet 41: requested right wheel velocity (mm/s).
    pub right_velocity: i16,
    /// Packet 42: requested left wheel velocity (mm/s).
    pub left_velocity: i16,
    /// Packet 43: left encoder counts.
    pub left_encoder: u16,
    /// Packet 44: right encoder counts.
    pub right_encoder: u16,
    /// Packet 45: light bumper bits.
    pub light_bumper: u8,
    /// Packets 46-51: light bump signals, left to right.
    pub light_signal: [u16; 6],
    /// Packets 52, 53: IR characters left and right.
    pub ir_left_right: [u8; 2],
    /// Packets 54-57: left wheel, right wheel, main brush, side brush currents (mA).
    pub motor_current: [i16; 4],
    /// Packet 58: stasis (bit 0 toggling, bit 1 disabled).
    pub stasis: u8,
}

/// Data of one packet; the largest is group 100 (80 bytes).
pub type PacketBytes = HVec<u8, 80>;

/// Appends single packet `id`'s data from `s`; unused packets (16, 32, 33)
/// are zeros. Ids that are no single packet add nothing.
fn push_single(id: u8, s: &SensorState, o: &mut PacketBytes) {
    let mut one = |b: u8| {
        let _ = o.push(b);
    };
    let word = |v: u16| v.to_be_bytes();
    let bytes: [u8; 2] = match id {
        7 => return one(s.bumps_drops),
        8 => return one(s.wall),
        9..=12 => return one(s.cliff[usize::from(id - 9)]),
        13 => return one(s.virtual_wall),
        14 => return one(s.overcurrents),
        15 => return one(s.dirt),
        16 | 32 => return one(0),
        17 => return one(s.ir_omni),
        18 => return one(s.buttons),
        21 => return one(s.charging_state),
        24 => return one(s.temperature_c as u8),
        34 => return one(s.charging_sources),
        35 => return one(s.oi_mode),
        36 => return one(s.song_number),
        37 => return one(s.song_playing),
        38 => return one(s.stream_packets),
        45 => return one(s.light_bumper),
        52 | 53 => return one(s.ir_left_right[usize::from(id - 52)]),
        58 => return one(s.stasis),
        19 => s.distance_mm.to_be_bytes(),
        20 => s.angle_deg.to_be_bytes(),
        22 => word(s.voltage_mv),
        23 => s.current_ma.to_be_bytes(),
        25 => word(s.charge_mah),
        26 => word(s.capacity_mah),
        27 => word(s.wall_signal),
        28..=31 => word(s.cliff_signal[usize::from(id - 28)]),
        33 => [0, 0],
        39 => s.velocity.to_be_bytes(),
        40 => s.radius.to_be_bytes(),
        41 => s.right_velocity.to_be_bytes(),
        42 => s.left_velocity.to_be_bytes(),
        43 => word(s.left_encoder),
        44 => word(s.right_encoder),
        46..=51 => word(s.light_signal[usize::from(id - 46)]),
        54..=57 => s.motor_current[usize::from(id - 54)].to_be_bytes(),
        _ => return,
    };
    let _ = o.extend_from_slice(&bytes);
}

/// The data bytes of packet `id` (single or group, as a Sensors or Query List
/// reply carries them: no id, no checksum); empty for undefined ids.
pub fn packet_bytes(id: u8, s: &SensorState) -> PacketBytes {
    let mut o = PacketBytes::new();
    match group_members(id) {
        Some(members) => members.for_each(|m| push_single(m, s, &mut o)),
        None => push_single(id, s, &mut o),
    }
    o
}

/// A stream frame on the wire: `n` is one byte, so at most 255 payload bytes.
pub type FrameBytes = HVec<u8, { 255 + 3 }>;

/// Encodes a stream frame with packets `ids` (single or group) from `s`
/// (device side). Undefined ids are left out, and so are packets that would
/// overflow the frame (the specification leaves it to the host not to ask
/// for more than fits).
pub fn encode_stream_frame(ids: &[u8], s: &SensorState) -> FrameBytes {
    let mut o = FrameBytes::new();
    let _ = o.push(STREAM_HEADER);
    let _ = o.push(0);
    for &id in ids {
        let data = packet_bytes(id, s);
        if data.is_empty() || o.len() + 1 + data.len() > 255 + 2 {
            continue;
        }
        let _ = o.push(id);
        let _ = o.extend_from_slice(&data);
    }
    o[1] = (o.len() - 2) as u8;
    let sum = o.iter().fold(0u8, |a, &b| a.wrapping_add(b));
    let _ = o.push(0u8.wrapping_sub(sum));
    o
}
