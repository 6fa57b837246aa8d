//! The `KEY:value` replies: VV (version), PP (parameters) and II (state),
//! parsed by key (never by position), unknown keys kept in order. PP also
//! gives the geometry helpers the driver needs: the angle of a step, the scan
//! period, the time per step, all from the sensor's own answer.

use core::f64::consts::TAU;
use core::fmt::Write as _;

use super::error_codes::ModelFamily;
use super::reply::ReplyError;
use super::sink::{ByteSink, EncodeError};

/// One `KEY:value` payload line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KvLine<'a> {
    /// The key (before the first `:`).
    pub key: &'a str,
    /// The value (after it).
    pub value: &'a str,
}

impl<'a> KvLine<'a> {
    /// Splits a `KEY:value` payload.
    pub fn parse(payload: &'a [u8]) -> Result<Self, ReplyError> {
        let text = core::str::from_utf8(payload).map_err(|_| ReplyError::NotText)?;
        let (key, value) = text.split_once(':').ok_or(ReplyError::NotKeyValue)?;
        Ok(KvLine { key, value })
    }

    /// Writes `KEY:value;X` + LF with the checksum excluding the `;`.
    pub fn encode(key: &str, value: &str, out: &mut impl ByteSink) -> Result<(), EncodeError> {
        for &b in key.as_bytes().iter().chain(value.as_bytes()) {
            if !(0x20..=0x7e).contains(&b) {
                return Err(EncodeError::BadText(b));
            }
        }
        if key.contains(':') || key.contains(';') {
            return Err(EncodeError::BadText(b':'));
        }
        let sum = key
            .as_bytes()
            .iter()
            .chain(b":")
            .chain(value.as_bytes())
            .fold(0u8, |acc, &b| acc.wrapping_add(b));
        let sum = (sum & 0x3f) + 0x30;
        out.put(key.as_bytes())?;
        out.put(b":")?;
        out.put(value.as_bytes())?;
        out.put(&[b';', sum, b'\n'])
    }
}

/// Most unknown `KEY:value` pairs a reply keeps (URG and UTM firmware send
/// none to three); more are dropped.
pub const MAX_EXTRA: usize = 8;

/// Longest key kept (SCIP keys are four letters); a longer one is not a
/// `KEY:value` line.
pub const MAX_KEY: usize = 8;

/// Text of at most `N` bytes: a value a sensor sent, owned without
/// allocating.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash)]
pub struct ShortText<const N: usize>(heapless::String<N>);

/// Longest value kept (bytes); a longer one is cut. The URG-04LX's longest,
/// II's `SCSP`, is 42; UTM firmware strings are shorter.
pub const MAX_VALUE: usize = 64;

/// A text value of a `KEY:value` line (see [`MAX_VALUE`]).
pub type Text = ShortText<MAX_VALUE>;

/// The start of an echo that is not a command, as kept in an error.
pub type Echo = ShortText<24>;

impl<const N: usize> ShortText<N> {
    /// `s`, cut at the capacity (on a character boundary) if longer.
    pub fn new(s: &str) -> Self {
        let mut t = heapless::String::new();
        for c in s.chars() {
            if t.push(c).is_err() {
                break;
            }
        }
        ShortText(t)
    }

    /// `bytes` as text, each byte that is not printable ASCII as `?`, cut at
    /// the capacity.
    pub fn from_bytes_lossy(bytes: &[u8]) -> Self {
        let mut t = heapless::String::new();
        for &b in bytes {
            let c = if (0x20..=0x7e).contains(&b) {
                b as char
            } else {
                '?'
            };
            if t.push(c).is_err() {
                break;
            }
        }
        ShortText(t)
    }

    /// The text.
    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl<const N: usize> core::ops::Deref for ShortText<N> {
    type Target = str;
    fn deref(&self) -> &str {
        &self.0
    }
}

impl<const N: usize> core::fmt::Display for ShortText<N> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(&self.0)
    }
}

impl<const N: usize> From<&str> for ShortText<N> {
    fn from(s: &str) -> Self {
        ShortText::new(s)
    }
}

impl<const N: usize> PartialEq<str> for ShortText<N> {
    fn eq(&self, other: &str) -> bool {
        self.0.as_str() == other
    }
}

impl<const N: usize> PartialEq<&str> for ShortText<N> {
    fn eq(&self, other: &&str) -> bool {
        self.0.as_str() == *other
    }
}

/// A key of an unknown `KEY:value` pair.
pub type Key = heapless::String<MAX_KEY>;

/// Unknown or extra `KEY:value` pairs, in the order received (the first
/// [`MAX_EXTRA`]).
pub type Extra = heapless::Vec<(Key, Text), MAX_EXTRA>;

/// Keeps an unknown pair if there is room (see [`MAX_EXTRA`]).
fn keep_extra(extra: &mut Extra, kv: &KvLine<'_>) -> Result<(), ReplyError> {
    let key = Key::try_from(kv.key).map_err(|_| ReplyError::NotKeyValue)?;
    let _ = extra.push((key, Text::new(kv.value)));
    Ok(())
}

/// The VV reply.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct VersionInfo {
    /// `VEND`: vendor.
    pub vendor: Text,
    /// `PROD`: product.
    pub product: Text,
    /// `FIRM`: firmware version.
    pub firmware: Text,
    /// `PROT`: protocol version.
    pub protocol: Text,
    /// `SERI`: serial number.
    pub serial: Text,
    /// Other keys.
    pub extra: Extra,
}

/// The PP reply: the sensor's own geometry and range limits.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SensorParams {
    /// `MODL`: model string, e.g. `URG-04LX(Hokuyo Automatic Co.,Ltd.)`.
    pub model: Text,
    /// `DMIN`: smallest valid range (mm); smaller values are error codes.
    pub dmin: u32,
    /// `DMAX`: largest valid range (mm).
    pub dmax: u32,
    /// `ARES`: steps per full turn.
    pub ares: u32,
    /// `AMIN`: first measurable step.
    pub amin: u32,
    /// `AMAX`: last measurable step.
    pub amax: u32,
    /// `AFRT`: the step pointing straight ahead.
    pub afrt: u32,
    /// `SCAN`: motor speed (rpm).
    pub scan_rpm: u32,
    /// Other keys (newer models add e.g. the scan direction).
    pub extra: Extra,
}

/// The II reply.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SensorInfo {
    /// `MODL`: model string.
    pub model: Text,
    /// `LASR`: laser state as sent (`ON`/`OFF`).
    pub laser: Text,
    /// `SCSP`: motor speed text.
    pub scan_speed: Text,
    /// `MESM`: measuring mode text.
    pub measure_mode: Text,
    /// `SBPS`: bit rate text.
    pub bit_rate: Text,
    /// `TIME`: raw text (6 hex digits on a URG-04LX, other forms elsewhere).
    pub time_raw: Text,
    /// `STAT`: sensor state text.
    pub state: Text,
    /// Other keys.
    pub extra: Extra,
}

impl SensorInfo {
    /// `LASR` as a flag, when it is `ON` or `OFF`.
    pub fn laser_on(&self) -> Option<bool> {
        match self.laser.trim() {
            "ON" => Some(true),
            "OFF" => Some(false),
            _ => None,
        }
    }

    /// `TIME` in milliseconds: 6 hex digits (URG-04LX firmware 3.x) or a
    /// 4-character SCIP field. Use TM1 for time sync, not this.
    pub fn time_ms(&self) -> Option<u32> {
        let t = self.time_raw.trim();
        if t.len() == 6 && t.bytes().all(|b| b.is_ascii_hexdigit()) {
            return u32::from_str_radix(t, 16).ok();
        }
        if t.len() == 4 {
            return super::encoding::decode_value(t.as_bytes()).ok();
        }
        None
    }
}

fn parse_num(key: &'static str, value: &str) -> Result<u32, ReplyError> {
    value
        .trim()
        .parse::<u32>()
        .map_err(|_| ReplyError::BadParameter(key))
}

fn pairs<'a>(
    lines: impl Iterator<Item = &'a [u8]>,
) -> impl Iterator<Item = Result<KvLine<'a>, ReplyError>> {
    lines.map(KvLine::parse)
}

impl VersionInfo {
    /// Parses the payload lines of a VV reply.
    pub fn parse<'a>(lines: impl Iterator<Item = &'a [u8]>) -> Result<Self, ReplyError> {
        let mut v = VersionInfo::default();
        for kv in pairs(lines) {
            let kv = kv?;
            let slot = match kv.key {
                "VEND" => &mut v.vendor,
                "PROD" => &mut v.product,
                "FIRM" => &mut v.firmware,
                "PROT" => &mut v.protocol,
                "SERI" => &mut v.serial,
                _ => {
                    keep_extra(&mut v.extra, &kv)?;
                    continue;
                }
            };
            *slot = Text::new(kv.value);
        }
        Ok(v)
    }

    /// Writes the data lines of a VV reply (without echo, status or end).
    pub fn encode_lines(&self, out: &mut impl ByteSink) -> Result<(), EncodeError> {
        KvLine::encode("VEND", &self.vendor, out)?;
        KvLine::encode("PROD", &self.product, out)?;
        KvLine::encode("FIRM", &self.firmware, out)?;
        KvLine::encode("PROT", &self.protocol, out)?;
        KvLine::encode("SERI", &self.serial, out)?;
        for (k, v) in &self.extra {
            KvLine::encode(k, v, out)?;
        }
        Ok(())
    }
}

impl SensorParams {
    /// The real URG-04LX answer (firmware 3.1.04): the emulator's default.
    pub fn urg_04lx() -> Self {
        SensorParams {
            model: Text::new("URG-04LX(Hokuyo Automatic Co.,Ltd.)"),
            dmin: 20,
            dmax: 5600,
            ares: 1024,
            amin: 44,
            amax: 725,
            afrt: 384,
            scan_rpm: 600,
            extra: Extra::new(),
        }
    }

    /// Parses the payload lines of a PP reply; every one of the seven numeric
    /// keys must be present, numeric and consistent.
    pub fn parse<'a>(lines: impl Iterator<Item = &'a [u8]>) -> Result<Self, ReplyError> {
        let mut model = None;
        let mut nums: [Option<u32>; 7] = [None; 7];
        const KEYS: [&str; 7] = ["DMIN", "DMAX", "ARES", "AMIN", "AMAX", "AFRT", "SCAN"];
        let mut extra = Extra::new();
        for kv in pairs(lines) {
            let kv = kv?;
            if kv.key == "MODL" {
                model = Some(Text::new(kv.value));
            } else if let Some(i) = KEYS.iter().position(|k| *k == kv.key) {
                nums[i] = Some(parse_num(KEYS[i], kv.value)?);
            } else {
                keep_extra(&mut extra, &kv)?;
            }
        }
        let get = |i: usize| nums[i].ok_or(ReplyError::MissingParameter(KEYS[i]));
        let p = SensorParams {
            model: model.ok_or(ReplyError::MissingParameter("MODL"))?,
            dmin: get(0)?,
            dmax: get(1)?,
            ares: get(2)?,
            amin: get(3)?,
            amax: get(4)?,
            afrt: get(5)?,
            scan_rpm: get(6)?,
            extra,
        };
        p.validate()?;
        Ok(p)
    }

    /// Checks the values are usable: ARES and SCAN non-zero, DMIN < DMAX,
    /// AMIN ≤ AFRT ≤ AMAX ≤ 9999 (the widest step field of a scan command).
    pub fn validate(&self) -> Result<(), ReplyError> {
        if self.ares == 0 {
            return Err(ReplyError::BadParameter("ARES"));
        }
        if self.scan_rpm == 0 {
            return Err(ReplyError::BadParameter("SCAN"));
        }
        if self.dmin >= self.dmax {
            return Err(ReplyError::BadParameter("DMAX"));
        }
        if self.amin > self.amax || self.amax > 9999 {
            return Err(ReplyError::BadParameter("AMAX"));
        }
        if self.afrt < self.amin || self.afrt > self.amax {
            return Err(ReplyError::BadParameter("AFRT"));
        }
        Ok(())
    }

    /// Writes the data lines of a PP reply.
    pub fn encode_lines(&self, out: &mut impl ByteSink) -> Result<(), EncodeError> {
        KvLine::encode("MODL", &self.model, out)?;
        for (k, v) in [
            ("DMIN", self.dmin),
            ("DMAX", self.dmax),
            ("ARES", self.ares),
            ("AMIN", self.amin),
            ("AMAX", self.amax),
            ("AFRT", self.afrt),
            ("SCAN", self.scan_rpm),
        ] {
            let mut digits = heapless::String::<10>::new();
            write!(digits, "{v}").map_err(|_| EncodeError::Overflow)?;
            KvLine::encode(k, &digits, out)?;
        }
        for (k, v) in &self.extra {
            KvLine::encode(k, v, out)?;
        }
        Ok(())
    }

    /// The error-code table family from `MODL`.
    pub fn family(&self) -> ModelFamily {
        ModelFamily::from_model(&self.model)
    }

    /// Angle of one step (rad).
    pub fn step_angle(&self) -> f64 {
        TAU / f64::from(self.ares.max(1))
    }

    /// Angle of step `step` in the sensor frame (rad, counter-clockwise, 0 = AFRT).
    pub fn angle_of_step(&self, step: f64) -> f64 {
        (step - f64::from(self.afrt)) * self.step_angle()
    }

    /// The nearest step to `angle` (rad), clamped to AMIN..=AMAX.
    pub fn step_of_angle(&self, angle: f64) -> u32 {
        let s = crate::float::round(angle / self.step_angle()) + f64::from(self.afrt);
        if s.is_nan() {
            return self.afrt;
        }
        s.clamp(f64::from(self.amin), f64::from(self.amax)) as u32
    }

    /// Number of measurable steps (AMAX − AMIN + 1).
    pub fn step_count(&self) -> u32 {
        self.amax.saturating_sub(self.amin) + 1
    }

    /// Time of one full turn (s).
    pub fn scan_period(&self) -> f64 {
        60.0 / f64::from(self.scan_rpm.max(1))
    }

    /// Time between two neighbouring steps (s).
    pub fn time_per_step(&self) -> f64 {
        self.scan_period() / f64::from(self.ares.max(1))
    }

    /// Time of step `step` after the first measurable step (AMIN) within one
    /// scan (s), for deskewing a scan taken while moving.
    pub fn time_of_step(&self, step: f64) -> f64 {
        (step - f64::from(self.amin)) * self.time_per_step()
    }

    /// Field of view from AMIN to AMAX (rad).
    pub fn field_of_view(&self) -> f64 {
        f64::from(self.amax.saturating_sub(self.amin)) * self.step_angle()
    }
}

impl SensorInfo {
    /// Parses the payload lines of an II reply.
    pub fn parse<'a>(lines: impl Iterator<Item = &'a [u8]>) -> Result<Self, ReplyError> {
        let mut v = SensorInfo::default();
        for kv in pairs(lines) {
            let kv = kv?;
            let slot = match kv.key {
                "MODL" => &mut v.model,
                "LASR" => &mut v.laser,
                "SCSP" => &mut v.scan_speed,
                "MESM" => &mut v.measure_mode,
                "SBPS" => &mut v.bit_rate,
                "TIME" => &mut v.time_raw,
                "STAT" => &mut v.state,
                _ => {
                    keep_extra(&mut v.extra, &kv)?;
                    continue;
                }
            };
            *slot = Text::new(kv.value);
        }
        Ok(v)
    }

    /// Writes the data lines of an II reply.
    pub fn encode_lines(&self, out: &mut impl ByteSink) -> Result<(), EncodeError> {
        KvLine::encode("MODL", &self.model, out)?;
        KvLine::encode("LASR", &self.laser, out)?;
        KvLine::encode("SCSP", &self.scan_speed, out)?;
        KvLine::encode("MESM", &self.measure_mode, out)?;
        KvLine::encode("SBPS", &self.bit_rate, out)?;
        KvLine::encode("TIME", &self.time_raw, out)?;
        KvLine::encode("STAT", &self.state, out)?;
        for (k, v) in &self.extra {
            KvLine::encode(k, v, out)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vv(lines: &[&str]) -> Result<VersionInfo, ReplyError> {
        VersionInfo::parse(lines.iter().map(|l| l.as_bytes()))
    }

    /// The fixed capacities on hostile text: a value beyond [`MAX_VALUE`]
    /// is cut, unknown keys beyond [`MAX_EXTRA`] are dropped, a key beyond
    /// [`MAX_KEY`] is refused with a typed error; none panics.
    #[test]
    fn overlong_text_is_cut_or_refused_never_a_panic() {
        let long = "x".repeat(3 * MAX_VALUE);
        let v = vv(&[&format!("VEND:{long}")]).unwrap();
        assert_eq!(v.vendor.len(), MAX_VALUE);
        // A multi-byte character straddling the capacity is left out whole.
        let v = vv(&[&format!("PROD:{}é", "y".repeat(MAX_VALUE - 1))]).unwrap();
        assert_eq!(v.product.len(), MAX_VALUE - 1);

        let keys: Vec<String> = (0..MAX_EXTRA + 4).map(|i| format!("K{i:03}:v")).collect();
        let refs: Vec<&str> = keys.iter().map(String::as_str).collect();
        let v = vv(&refs).unwrap();
        assert_eq!(v.extra.len(), MAX_EXTRA);
        assert_eq!(v.extra[0].0.as_str(), "K000");

        let e = vv(&[&format!("{}:v", "K".repeat(MAX_KEY + 1))]).unwrap_err();
        assert_eq!(e, ReplyError::NotKeyValue);
    }

    #[test]
    fn an_unknown_echo_is_kept_short_and_printable() {
        let e = Echo::from_bytes_lossy(b"ZZ\x01\xff and a great deal more than fits");
        assert_eq!(e.len(), 24);
        assert!(e.starts_with("ZZ??"), "{e}");
    }
}
