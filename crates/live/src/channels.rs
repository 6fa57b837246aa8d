//! The Foxglove channels the telemetry thread logs on, in one context
//! (every sink of the context gets every channel).

use std::sync::Arc;

use foxglove::schemas::{FrameTransform, LaserScan, PoseInFrame, SceneUpdate};
use foxglove::{Channel, ChannelBuilder, Context, RawChannel, Schema};

use crate::topics;

/// A JSON channel with a JSON schema.
fn json_channel(ctx: &Arc<Context>, topic: &str, name: &str, schema: &str) -> Arc<RawChannel> {
    ChannelBuilder::new(topic)
        .context(ctx)
        .message_encoding("json")
        .schema(Schema::new(name, "jsonschema", schema.as_bytes().to_vec()))
        .build_raw()
        .expect("a JSON channel with a schema is valid")
}

/// The channels.
pub(crate) struct Channels {
    pub(crate) scan: Channel<LaserScan>,
    pub(crate) scan_input: Arc<RawChannel>,
    pub(crate) odometry_input: Arc<RawChannel>,
    pub(crate) pose: Channel<PoseInFrame>,
    pub(crate) odom: Channel<PoseInFrame>,
    pub(crate) tf: Channel<FrameTransform>,
    pub(crate) map: Channel<foxglove::schemas::Grid>,
    pub(crate) swept: Channel<foxglove::schemas::Grid>,
    pub(crate) plan: Channel<SceneUpdate>,
    pub(crate) status: Arc<RawChannel>,
    pub(crate) log: Channel<foxglove::schemas::Log>,
    pub(crate) truth: Option<Channel<PoseInFrame>>,
}

impl Channels {
    pub(crate) fn new(ctx: &Arc<Context>, sim: bool) -> Self {
        Self {
            scan: ChannelBuilder::new(topics::SCAN).context(ctx).build(),
            scan_input: json_channel(
                ctx,
                topics::SCAN_INPUT,
                "sweepline.ScanInput",
                SCAN_INPUT_SCHEMA,
            ),
            odometry_input: json_channel(
                ctx,
                topics::ODOMETRY_INPUT,
                "sweepline.OdometryInput",
                ODOMETRY_INPUT_SCHEMA,
            ),
            pose: ChannelBuilder::new(topics::POSE).context(ctx).build(),
            odom: ChannelBuilder::new(topics::ODOM).context(ctx).build(),
            tf: ChannelBuilder::new(topics::TF).context(ctx).build(),
            map: ChannelBuilder::new(topics::MAP).context(ctx).build(),
            swept: ChannelBuilder::new(topics::SWEPT).context(ctx).build(),
            plan: ChannelBuilder::new(topics::PLAN).context(ctx).build(),
            status: json_channel(
                ctx,
                topics::STATUS,
                "sweepline.Status",
                crate::status::SCHEMA,
            ),
            log: ChannelBuilder::new(topics::LOG).context(ctx).build(),
            truth: sim.then(|| ChannelBuilder::new(topics::TRUTH).context(ctx).build()),
        }
    }
}

/// The JSON schema of [`topics::SCAN_INPUT`].
const SCAN_INPUT_SCHEMA: &str = r#"{"type":"object","title":"sweepline.ScanInput","properties":{
"stamp":{"type":"number"},"seq":{"type":"integer"},
"odom":{"type":"array","items":{"type":"number"}},"odom_current":{"type":"boolean"},
"interval":{"type":"number"},"motion":{"type":"array","items":{"type":"number"}},
"first_beam_time":{"type":"number"},"beam_interval":{"type":"number"},
"angles":{"type":"array","items":{"type":"number"}},"ranges":{"type":"array","items":{"type":"number"}},
"intensities":{"type":"array","items":{"type":"number"}},"invalid":{"type":"array","items":{"type":"integer"}},
"raw_stamp":{"type":"integer"},"sensor_ms":{"type":"integer"},"epoch":{"type":"integer"},
"dropped_before":{"type":"integer"},"raw":{"type":"array","items":{"type":"integer"}}}}"#;

/// The JSON schema of [`topics::ODOMETRY_INPUT`].
const ODOMETRY_INPUT_SCHEMA: &str = r#"{"type":"object","title":"sweepline.OdometryInput","properties":{
"t0":{"type":"number"},"t1":{"type":"number"},
"delta":{"type":"array","items":{"type":"number"}},
"left":{"type":"number"},"right":{"type":"number"}}}"#;
