//! The JSON Schemas of the recording's channels (hand-written;
//! tests/formats/sink_messages.rs checks them against the structs).

use serde_json::{Value, json};

use crate::units;

fn uint(description: &str) -> Value {
    json!({"type": "integer", "minimum": 0, "description": description})
}

fn number(description: &str) -> Value {
    json!({"type": "number", "description": description})
}

fn nullable_number(description: &str) -> Value {
    json!({"type": ["number", "null"], "description": description})
}

fn object(title: &str, description: &str, properties: Value) -> Value {
    let required: Vec<String> = properties
        .as_object()
        .map(|p| p.keys().cloned().collect())
        .unwrap_or_default();
    json!({
        "title": title,
        "description": description,
        "type": "object",
        "properties": properties,
        "required": required,
        "additionalProperties": false,
    })
}

pub(super) fn raw_batch_schema() -> Value {
    let gap = object(
        "sagnac.Gap",
        "lost samples missing just before counts[index]",
        json!({
            "index": uint("position in counts the gap precedes"),
            "lost": {"type": "integer", "minimum": 1, "description": "number of missing samples"},
        }),
    );
    object(
        "sagnac.RawBatch",
        "a batch of per-sample pulse increments from the gyro",
        json!({
            "t0_ns": uint("time of the first sample, ns since the Unix epoch"),
            "dt_ns": uint("sample period, ns"),
            "seq0": uint("device sequence number of the first sample"),
            "counts": {"type": "array", "items": {"type": "integer"}, "description": "pulse increments per sample"},
            "gaps": {"type": "array", "items": gap, "description": "missing samples"},
            "temp_c": nullable_number("device temperature, deg C"),
            "status": uint("device status word of the last frame"),
        }),
    )
}

pub(super) fn rate_batch_schema(what: &str) -> Value {
    object(
        "sagnac.RateBatch",
        &format!("a batch of uniformly spaced rate values: {what}, deg/h"),
        json!({
            "t0_ns": uint("time of the first value, ns since the Unix epoch"),
            "dt_ns": uint("spacing of the values, ns"),
            "values": {"type": "array", "items": {"type": "number"}, "description": "rate, deg/h, recorded to 1e-3 deg/h (three decimals; one counter pulse at 1 kHz is about 1210 deg/h for the paper gyro)"},
        }),
    )
}

/// One coefficient as `sagnac analyze --json` writes it: `value` and `ci95`, or
/// `value: null` and `upper95`.
fn coefficient_schema(key: &str, unit: &str, what: &str) -> Value {
    json!({
        "title": "sagnac.Coefficient",
        "description": format!("{what}, {unit}: value with its 95 % interval, or null with a 95 % upper bound when the data do not resolve it"),
        "type": "object",
        "properties": {
            "value": nullable_number(&format!("{key}: point estimate, {unit} (null: only an upper bound)")),
            "ci95": {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2,
                     "description": format!("95 % interval [lower, upper], {unit}")},
            "upper95": number(&format!("95 % upper bound, {unit} (when value is null)")),
        },
        "required": ["value"],
        "additionalProperties": false,
    })
}

pub(super) fn estimate_update_schema() -> Value {
    let mut coefficients = serde_json::Map::new();
    for (key, unit, what) in units::COEFFICIENTS {
        coefficients.insert(key.to_string(), coefficient_schema(key, unit, what));
    }
    let names: Vec<&str> = units::COEFFICIENTS.iter().map(|c| c.0).collect();
    let mut schema = object(
        "sagnac.EstimateUpdate",
        "noise-coefficient estimates, named as in `sagnac analyze --json` (units in the names)",
        json!({
            "t_ns": uint("time of the update, ns since the Unix epoch"),
            "samples": uint("samples used"),
            "duration_s": number("span of data used, s"),
            "estimates": object(
                "sagnac.NoiseEstimates",
                &format!("the IEEE 952 coefficients: {}", names.join(", ")),
                Value::Object(coefficients),
            ),
        }),
    );
    // optional: absent with the raw statistics
    schema["properties"]["data_quality"] = data_quality_schema();
    schema
}

/// `data_quality`, as `sagnac analyze --json` writes it.
fn data_quality_schema() -> Value {
    let nullable = |mut o: Value| {
        o["type"] = json!(["object", "null"]);
        o
    };
    let interval = |what: &str| {
        object(
            "sagnac.Interval",
            &format!("{what}: value with its 95 % interval"),
            json!({
                "value": number(what),
                "ci95": {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2,
                         "description": format!("95 % interval [lower, upper] of the {what}")},
            }),
        )
    };
    let outliers = object(
        "sagnac.Outliers",
        "single-sample glitches, found by a robust test against the record's own noise",
        json!({
            "count": uint("outliers found"),
            "at_s": {"type": "array", "items": {"type": "number"}, "description": "their times, s from the start of the run (the first 1000)"},
            "threshold_sigma": number("the test's threshold, standard deviations of its statistic"),
            "excluded": {"type": "boolean", "description": "every one excluded from the statistics as a gap (false: in windows whose noise is heavy-tailed they were kept)"},
            "excluded_count": uint("how many were excluded"),
            "excess_kurtosis": nullable_number("excess kurtosis of the test statistic over the samples kept (0 for Gaussian noise)"),
            "heavy_tailed_windows": uint("windows of the record whose noise is heavy-tailed"),
        }),
    );
    let warmup = object(
        "sagnac.Warmup",
        "a warm-up: the bias settles as amplitude_dph exp(-t / tau_s) from the start",
        json!({
            "amplitude_dph": interval("amplitude, deg/h"),
            "tau_s": interval("time constant, s"),
            "handled": {"type": "string", "enum": ["modelled", "excluded"],
                        "description": "modelled (the fitted settling subtracted; the daemon before its restart: in the statistics) or excluded (the statistics restarted after it)"},
            "excluded_s": number("seconds of the run left out of the statistics"),
        }),
    );
    let step = object(
        "sagnac.BiasStep",
        "a bias step: the bias jumps by amplitude_dph at at_s",
        json!({
            "at_s": interval("time of the step, s from the start of the run"),
            "amplitude_dph": interval("size of the step, deg/h"),
        }),
    );
    let thermal = object(
        "sagnac.Thermal",
        "the bias's response to the temperature, delayed by lag_s",
        json!({
            "bias_sensitivity_dph_per_c": interval("sensitivity, deg/h per deg C"),
            "lag_s": interval("lag, s"),
            "compensated": {"type": "boolean", "description": "the response is significant and the rate is compensated for it"},
            "confounded_with_ramp": {"type": "boolean", "description": "the temperature changed linearly: its response was fitted in place of a rate ramp, which it cannot be told from (when the response is not significant, the ramp is reported as a bound), and the lag is not identified"},
        }),
    );
    let stationary = object(
        "sagnac.Stationarity",
        "whether the windows of the record share one noise (dynamic Allan deviation)",
        json!({
            "ok": {"type": "boolean", "description": "false when the windows' noise differs beyond chance"},
            "test": {"type": "string", "description": "what was tested"},
            "p_value": number("the record's p-value"),
        }),
    );
    object(
        "sagnac.DataQuality",
        "what the data-quality stage found and did, as `sagnac analyze --json` names it",
        json!({
            "outliers": outliers,
            "warmup": nullable(warmup),
            "steps": {"type": "array", "items": step, "description": "bias steps found"},
            "thermal": nullable(thermal),
            "stationary": nullable(stationary),
        }),
    )
}

pub(super) fn summary_update_schema() -> Value {
    let timestamp = object(
        "time",
        "time of the window's first sample since the Unix epoch (Foxglove time: sec, nsec)",
        json!({
            "sec": uint("whole seconds"),
            "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999, "description": "nanoseconds"},
        }),
    );
    object(
        "sagnac.SummaryUpdate",
        "0.1 s of samples as scalars (10 Hz), for plots over time",
        json!({
            "timestamp": timestamp,
            "samples": uint("sample periods in the window (gap-filled ones included)"),
            "lost_samples": uint("periods of the window whose sample was lost (gap-filled)"),
            "raw_rate_dph": number("mean raw rate over the window, deg/h, recorded to 1e-3 deg/h"),
            "clean_rate_dph": number("mean wavelet-cleaned rate over the window, deg/h, recorded to 1e-3 deg/h"),
            "temp_c": nullable_number("device temperature, deg C (null: the frames carry none)"),
        }),
    )
}

pub(super) fn allan_update_schema() -> Value {
    let numbers = |d: &str| json!({"type": "array", "items": {"type": "number"}, "description": d});
    let curve = object(
        "sagnac.AllanCurve",
        "an octave Allan-deviation curve, columns of equal length",
        json!({
            "tau_s": numbers("averaging time, s"),
            "dev": numbers("Allan deviation, deg/h"),
            "ci_lo": numbers("lower end of the confidence interval, deg/h"),
            "ci_hi": numbers("upper end of the confidence interval, deg/h"),
            "n": {"type": "array", "items": {"type": "integer", "minimum": 0}, "description": "terms averaged"},
        }),
    );
    object(
        "sagnac.AllanUpdate",
        "Allan-deviation curves per channel (raw, clean)",
        json!({
            "t_ns": uint("time of the update, ns since the Unix epoch"),
            "curves": {"type": "object", "additionalProperties": curve, "description": "channel -> curve"},
            "units": {"type": "object", "additionalProperties": {"type": "string"},
                      "description": "column -> its unit (tau_s: s; dev, ci_lo, ci_hi: deg/h; n: 1), as analyze --json's units"},
        }),
    )
}

/// The event kinds and their fields, in the order of [`EventKind`].
fn event_kinds() -> Vec<(&'static str, &'static str, Value)> {
    vec![
        (
            "gap",
            "samples missing",
            json!({"seq": uint("first missing sequence number"), "lost": uint("samples missing")}),
        ),
        (
            "resync",
            "frame sync lost and found again",
            json!({"byte_offset": uint("input byte offset where sync was found"), "skipped_bytes": uint("bytes skipped")}),
        ),
        (
            "crc_error",
            "a frame failed its CRC",
            json!({"byte_offset": uint("input byte offset of the frame")}),
        ),
        (
            "status_change",
            "the device status word changed",
            json!({"from": uint("previous status word"), "to": uint("new status word")}),
        ),
        (
            "device_disconnected",
            "the device went away",
            json!({"device": {"type": "string"}, "reason": {"type": "string"}}),
        ),
        (
            "device_reconnected",
            "the device is back",
            json!({"device": {"type": "string"}}),
        ),
        (
            "backpressure_drop",
            "messages dropped because a sink's queue was full",
            json!({"sink": {"type": "string"}, "dropped": uint("messages dropped")}),
        ),
    ]
}

pub(super) fn event_schema() -> Value {
    let kinds = event_kinds();
    let names: Vec<&str> = kinds.iter().map(|(k, _, _)| *k).collect();
    let branches: Vec<Value> = kinds
        .into_iter()
        .map(|(kind, description, fields)| {
            let mut props = json!({
                "t_ns": uint("time of the event, ns since the Unix epoch"),
                "kind": {"const": kind},
            });
            if let (Some(p), Some(f)) = (props.as_object_mut(), fields.as_object()) {
                p.extend(f.clone());
            }
            let mut branch = object(&format!("sagnac.Event.{kind}"), description, props);
            // optional: only a recording of several gyros names the gyro
            branch["properties"]["gyro"] =
                json!({"type": "string", "description": "the gyro it concerns, in a recording of several gyros"});
            branch
        })
        .collect();
    json!({
        "title": "sagnac.Event",
        "description": "an acquisition event; the fields depend on kind",
        "type": "object",
        "properties": {
            "t_ns": uint("time of the event, ns since the Unix epoch"),
            "kind": {"type": "string", "enum": names},
            "gyro": {"type": "string", "description": "the gyro it concerns, in a recording of several gyros"},
        },
        "required": ["t_ns", "kind"],
        "oneOf": branches,
    })
}

pub(super) fn verdict_update_schema() -> Value {
    let verdict = |d: &str| json!({"type": "string", "enum": ["pass", "fail", "undecided"], "description": d});
    let coefficient = json!({
        "title": "sagnac.CoefficientVerdict",
        "description": "one coefficient's verdict against its limit, in the unit its name carries",
        "type": "object",
        "properties": {
            "limit": number("the spec's upper limit"),
            "verdict": verdict("pass: below the limit; fail: above it; undecided"),
            "estimate": nullable_number("the estimate (null: only an upper bound, or none yet)"),
            "bound": nullable_number("the deciding bound at the verdict's confidence: upper for pass and undecided, lower for fail"),
            "lower": number("lower bound at the verdict's confidence"),
            "upper": number("upper bound at the verdict's confidence"),
            "reason": {"type": "string", "description": "why the coefficient is undecided"},
            "decided_at_s": number("record length at the decision, s"),
            "eta_s": number("predicted further record length until a decision, s"),
        },
        "required": ["limit", "verdict", "estimate", "bound"],
        "additionalProperties": false,
    });
    object(
        "sagnac.VerdictUpdate",
        "acceptance-test verdicts (anytime-valid: alpha spending over looks at geometrically spaced record lengths)",
        json!({
            "t_ns": uint("time of the update, ns since the Unix epoch"),
            "verdict": verdict("overall: fail if any coefficient fails, pass if all pass, else undecided"),
            "confidence": number("guaranteed confidence of each verdict"),
            "look": {"type": ["integer", "null"], "minimum": 0, "description": "look of the schedule the verdicts were evaluated at (null: none yet)"},
            "z": number("normal quantile of that look"),
            "duration_s": number("record length at that look, s"),
            "coefficients": {"type": "object", "additionalProperties": coefficient, "description": "coefficient name -> verdict"},
        }),
    )
}
