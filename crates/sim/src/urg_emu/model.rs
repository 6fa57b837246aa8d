//! What the emulated sensor says about itself: the exact VV, PP and II fields
//! of the real units captured in `../shared/datasets/hokuyo-captures/`
//! (URG-04LX firmware 3.1.04, UTM-30LX firmware P.1.05), plus the geometry
//! and timing the emulator derives from them.

use std::f64::consts::TAU;

/// Which sensor to emulate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Model {
    /// Hokuyo URG-04LX (SCIP 2.0 firmware 3.x over USB-CDC): 682 steps,
    /// 10 Hz, no ME (answers `0E`), FF intensity mode.
    Urg04lx,
    /// Hokuyo UTM-30LX: 1081 steps, 40 Hz, ME intensity.
    Utm30lx,
}

impl std::str::FromStr for Model {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "urg-04lx" | "urg04lx" | "urg" => Ok(Model::Urg04lx),
            "utm-30lx" | "utm30lx" | "utm" => Ok(Model::Utm30lx),
            _ => Err(format!(
                "unknown model `{s}`: expected urg-04lx or utm-30lx"
            )),
        }
    }
}

/// Fixed facts of one model.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelSpec {
    /// Which model.
    pub model: Model,
    /// VV reply fields, in order.
    pub vv: [(&'static str, &'static str); 5],
    /// MODL value (PP and II).
    pub(crate) modl: &'static str,
    /// Shortest valid range (mm); smaller values are error codes.
    pub dmin: u32,
    /// Longest range (mm).
    pub dmax: u32,
    /// Steps per revolution.
    pub ares: u32,
    /// First measurable step.
    pub amin: u16,
    /// Last step of the detection range (PP's AMAX).
    pub amax: u16,
    /// Last step a scan request may name ("step D" of the SCIP 2.0
    /// specification's measurement table: 768 on the URG-04LX, whose PP
    /// still says AMAX 725). Steps past AMAX look into the dead zone.
    pub(crate) last_step: u16,
    /// Step pointing forward.
    pub afrt: u16,
    /// Motor speed (rpm).
    pub scan_rpm: u32,
    /// II `SCSP` value.
    pub(crate) scsp: &'static str,
    /// II `SBPS` value.
    pub(crate) sbps: &'static str,
    /// Whether ME/GE exist (else answered `0E`).
    pub(crate) has_me: bool,
    /// Whether the `FF` cluster (URG-04LX raw intensity) exists.
    pub(crate) has_ff: bool,
    /// Status to a CR00 request (`03` on the URG-04LX, `04` on the UTM).
    pub(crate) cr_status: [u8; 2],
    /// Value sent for "no echo within range".
    pub(crate) no_return_code: u32,
    /// How long before a revolution starts the firmware answers commands
    /// other than GD/GS (s). The captures show every VV, PP, II, BM, CR and
    /// TM0 reply leaving at one fixed point of the revolution: on the
    /// URG-04LX the II `TIME` values end in 24 ms while its revolutions
    /// start at clock values ending in 30 ms (the GD stamp); on the UTM-30LX
    /// the ME ack leaves 3 ms before the first streamed revolution's stamp.
    pub(crate) tick_lead: f64,
}

impl ModelSpec {
    /// The spec of `model`.
    pub fn of(model: Model) -> ModelSpec {
        match model {
            Model::Urg04lx => ModelSpec {
                model,
                vv: [
                    ("VEND", "Hokuyo Automatic Co.,Ltd."),
                    ("PROD", "SOKUIKI Sensor URG-04LX"),
                    ("FIRM", "3.1.04(02/Aug./2007)"),
                    ("PROT", "SCIP 2.0"),
                    ("SERI", "H0706400"),
                ],
                modl: "URG-04LX(Hokuyo Automatic Co.,Ltd.)",
                dmin: 20,
                dmax: 5600,
                ares: 1024,
                amin: 44,
                amax: 725,
                last_step: 768,
                afrt: 384,
                scan_rpm: 600,
                scsp: "Initial(600[rpm])<-Default setting by user",
                sbps: "19200[bps]<-Default setting by user",
                has_me: false,
                has_ff: true,
                cr_status: *b"03",
                no_return_code: 0,
                tick_lead: 0.006,
            },
            Model::Utm30lx => ModelSpec {
                model,
                vv: [
                    ("VEND", "Hokuyo Automatic Co.,Ltd."),
                    ("PROD", "SOKUIKI Sensor TOP-URG UTM-30LX"),
                    ("FIRM", "P.1.05(17/Apr./2009)"),
                    ("PROT", "SCIP 2.0"),
                    ("SERI", "00903971"),
                ],
                modl: "UTM-30LX(Hokuyo Automatic Co.,Ltd.)",
                dmin: 23,
                dmax: 60000,
                ares: 1440,
                amin: 0,
                amax: 1080,
                last_step: 1080,
                afrt: 540,
                scan_rpm: 2400,
                scsp: "Initial(2400[rpm])<-Default setting by user",
                sbps: "USB Full Speed",
                has_me: true,
                has_ff: false,
                cr_status: *b"04",
                no_return_code: 1,
                tick_lead: 0.003,
            },
        }
    }

    /// Seconds per revolution (one scan).
    pub fn period(&self) -> f64 {
        60.0 / f64::from(self.scan_rpm)
    }

    /// Beam angle of step `s` (rad, counter-clockwise, 0 = front).
    pub fn angle(&self, step: u16) -> f64 {
        (f64::from(step) - f64::from(self.afrt)) * TAU / f64::from(self.ares)
    }

    /// The PP fields, in the sensor's order.
    pub fn pp(&self) -> [(&'static str, String); 8] {
        [
            ("MODL", self.modl.to_string()),
            ("DMIN", self.dmin.to_string()),
            ("DMAX", self.dmax.to_string()),
            ("ARES", self.ares.to_string()),
            ("AMIN", self.amin.to_string()),
            ("AMAX", self.amax.to_string()),
            ("AFRT", self.afrt.to_string()),
            ("SCAN", self.scan_rpm.to_string()),
        ]
    }

    /// The II fields for a laser state and a sensor clock value (ms); the
    /// time is 6 hex digits as on the real firmware.
    pub fn ii(&self, laser_on: bool, sensor_ms: u32) -> [(&'static str, String); 7] {
        [
            ("MODL", self.modl.to_string()),
            ("LASR", if laser_on { "ON" } else { "OFF" }.to_string()),
            ("SCSP", self.scsp.to_string()),
            ("MESM", "CLASSIC".to_string()),
            ("SBPS", self.sbps.to_string()),
            ("TIME", format!("{:06X}", sensor_ms & 0xFF_FFFF)),
            ("STAT", "Sensor works well.".to_string()),
        ]
    }
}
