//! The MCAP message structs and their JSON Schemas: every message validates against
//! its channel's schema (checked by a small structural validator written here, and
//! also by the Python `jsonschema` package in tests/formats/sink_mcap.rs when installed),
//! the validator rejects broken messages, JSON round-trips exactly, and messages
//! JSON cannot carry are refused.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use sagnac::recording::messages::{
    AllanCurve, AllanUpdate, Event, EventKind, Gap, MessageError, RateBatch, RawBatch, SinkMessage,
    Topic, quantize_rate, recordable_quality,
};
use serde_json::{Value, json};

use crate::support::sink;

/// Structural JSON Schema check: type, properties, required, additionalProperties
/// (bool or schema), items, oneOf (exactly one), enum, const, minimum. Returns the
/// first violation with its JSON path.
fn check(schema: &Value, v: &Value, path: &str) -> Result<(), String> {
    let fail = |what: String| Err(format!("{path}: {what}"));
    if let Some(t) = schema.get("type") {
        let types: Vec<&str> = match t {
            Value::String(s) => vec![s.as_str()],
            Value::Array(a) => a.iter().filter_map(Value::as_str).collect(),
            _ => return fail(format!("bad type keyword {t}")),
        };
        let ok = types.iter().any(|t| match *t {
            "object" => v.is_object(),
            "array" => v.is_array(),
            "string" => v.is_string(),
            "boolean" => v.is_boolean(),
            "null" => v.is_null(),
            "number" => v.is_number(),
            "integer" => v.is_i64() || v.is_u64(),
            _ => false,
        });
        if !ok {
            return fail(format!("{v} is not of type {types:?}"));
        }
    }
    if let Some(c) = schema.get("const")
        && c != v
    {
        return fail(format!("{v} != const {c}"));
    }
    if let Some(Value::Array(options)) = schema.get("enum")
        && !options.contains(v)
    {
        return fail(format!("{v} not in enum {options:?}"));
    }
    if let (Some(min), Some(x)) = (schema.get("minimum").and_then(Value::as_f64), v.as_f64())
        && x < min
    {
        return fail(format!("{x} < minimum {min}"));
    }
    if let Some(obj) = v.as_object() {
        let props = schema.get("properties").and_then(Value::as_object);
        if let Some(Value::Array(req)) = schema.get("required") {
            for r in req.iter().filter_map(Value::as_str) {
                if !obj.contains_key(r) {
                    return fail(format!("missing required `{r}`"));
                }
            }
        }
        for (k, x) in obj {
            let sub = format!("{path}.{k}");
            match props.and_then(|p| p.get(k)) {
                Some(s) => check(s, x, &sub)?,
                None => match schema.get("additionalProperties") {
                    Some(Value::Bool(false)) => return fail(format!("unexpected property `{k}`")),
                    Some(s @ Value::Object(_)) => check(s, x, &sub)?,
                    _ => {}
                },
            }
        }
    }
    if let (Some(items), Some(arr)) = (schema.get("items"), v.as_array()) {
        for (i, x) in arr.iter().enumerate() {
            check(items, x, &format!("{path}[{i}]"))?;
        }
    }
    if let Some(Value::Array(branches)) = schema.get("oneOf") {
        let passing = branches
            .iter()
            .filter(|b| check(b, v, path).is_ok())
            .count();
        if passing != 1 {
            return fail(format!(
                "{passing} oneOf branches match, expected exactly 1"
            ));
        }
    }
    Ok(())
}

fn json_of(m: &SinkMessage) -> Value {
    serde_json::from_slice(&m.to_json().expect("serialize")).expect("valid JSON")
}

#[test]
fn every_message_validates_against_its_schema() {
    let messages = sink::stream(11, 600);
    for topic in Topic::ALL {
        assert!(
            messages.iter().any(|m| m.topic() == topic),
            "sample covers {topic:?}"
        );
    }
    for (i, m) in messages.iter().enumerate() {
        let schema = m.topic().json_schema();
        check(&schema, &json_of(m), "$").unwrap_or_else(|e| panic!("message {i}: {e}"));
    }
    // Every event kind is covered, and the schema's kind list is exactly serde's.
    let schema = Topic::Events.json_schema();
    let enum_kinds: Vec<&str> = schema["properties"]["kind"]["enum"]
        .as_array()
        .unwrap()
        .iter()
        .map(|k| k.as_str().unwrap())
        .collect();
    let mut seen: Vec<String> = messages
        .iter()
        .filter_map(|m| match m {
            SinkMessage::Event(_) => Some(json_of(m)["kind"].as_str().unwrap().to_string()),
            _ => None,
        })
        .collect();
    seen.sort();
    seen.dedup();
    let mut expected: Vec<String> = enum_kinds.iter().map(|s| s.to_string()).collect();
    expected.sort();
    assert_eq!(seen, expected);
}

#[test]
fn schema_properties_are_exactly_the_serialized_fields() {
    // additionalProperties:false + all-required on every object means the schema and
    // the struct agree both ways; check the flag is there for the fixed structs.
    for topic in [
        Topic::Raw,
        Topic::Clean,
        Topic::Estimates,
        Topic::Allan,
        Topic::Summary,
    ] {
        let s = topic.json_schema();
        assert_eq!(s["additionalProperties"], json!(false), "{topic:?}");
        // the one optional field: `data_quality`, absent with the raw statistics
        let props: Vec<&String> = s["properties"]
            .as_object()
            .unwrap()
            .keys()
            .filter(|k| !(topic == Topic::Estimates && *k == "data_quality"))
            .collect();
        let req: Vec<&str> = s["required"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r.as_str().unwrap())
            .collect();
        assert_eq!(
            props.len(),
            req.len(),
            "{topic:?}: every property is required"
        );
    }
    assert_eq!(
        Topic::Clean.json_schema()["title"],
        Topic::Noise.json_schema()["title"]
    );
    // data_quality's objects: every field required, no other
    let dq = &Topic::Estimates.json_schema()["properties"]["data_quality"];
    let mut objects = vec![dq.clone()];
    while let Some(o) = objects.pop() {
        if let Some(props) = o["properties"].as_object() {
            let req = o["required"].as_array().unwrap();
            assert_eq!(props.len(), req.len(), "{}", o["title"]);
            assert_eq!(o["additionalProperties"], json!(false), "{}", o["title"]);
            objects.extend(props.values().cloned());
        }
        if o["items"].is_object() {
            objects.push(o["items"].clone());
        }
    }
}

/// `data_quality` in `/gyro/estimates`: the field names of `sagnac analyze
/// --json`'s `data_quality` (the same serde structs), absent (not null) with
/// the raw statistics; the validator holds messages to its schema; numbers
/// JSON cannot carry are refused, and [`recordable_quality`] leaves out the
/// findings that hold them.
#[test]
fn data_quality_has_analyzes_names_and_is_optional() {
    let schema = Topic::Estimates.json_schema();
    let with: Vec<_> = sink::stream(21, 400)
        .into_iter()
        .filter_map(|m| match m {
            SinkMessage::Estimates(e) => Some(e),
            _ => None,
        })
        .collect();
    assert!(with.iter().any(|e| e.data_quality.is_none()));
    let mut kinds = std::collections::BTreeSet::new();
    for e in &with {
        let j = json_of(&SinkMessage::Estimates(e.clone()));
        check(&schema, &j, "$").unwrap();
        match &e.data_quality {
            None => assert!(j.get("data_quality").is_none(), "absent, not null"),
            Some(dq) => {
                assert_eq!(j["data_quality"], serde_json::to_value(dq).unwrap());
                for k in ["outliers", "warmup", "steps", "thermal", "stationary"] {
                    assert!(j["data_quality"].get(k).is_some(), "{k}");
                    if !j["data_quality"][k].is_null() {
                        kinds.insert(k);
                    }
                }
            }
        }
    }
    assert_eq!(
        kinds.len(),
        5,
        "every kind of finding is covered: {kinds:?}"
    );
    // the validator rejects a broken data_quality
    let good = json_of(&SinkMessage::Estimates(
        with.iter()
            .find(|e| e.data_quality.as_ref().is_some_and(|d| d.warmup.is_some()))
            .unwrap()
            .clone(),
    ));
    for (path, value) in [
        ("warmup", json!({"amplitude_dph": 1.0})),
        ("outliers", json!(null)),
        ("steps", json!([{"at_s": 1.0}])),
        ("thermal", json!(3)),
        ("extra", json!(1)),
    ] {
        let mut bad = good.clone();
        bad["data_quality"][path] = value.clone();
        assert!(
            check(&schema, &bad, "$").is_err(),
            "{path} = {value} accepted"
        );
    }
    let mut bad = good.clone();
    bad["data_quality"]["warmup"]["handled"] = json!("ignored");
    assert!(
        check(&schema, &bad, "$").is_err(),
        "handled is modelled or excluded"
    );
    // non-finite numbers: refused; the sanitiser drops what holds them
    let mut e = with
        .iter()
        .find(|e| {
            e.data_quality
                .as_ref()
                .is_some_and(|d| d.warmup.is_some() && d.outliers.count > 0)
        })
        .unwrap()
        .clone();
    let dq = e.data_quality.as_mut().unwrap();
    dq.warmup.as_mut().unwrap().tau_s.ci95[1] = f64::INFINITY;
    dq.outliers.at_s[0] = f64::NAN;
    dq.outliers.excess_kurtosis = Some(f64::NAN);
    let n_at = dq.outliers.at_s.len();
    let err = SinkMessage::Estimates(e.clone()).validate().unwrap_err();
    assert!(matches!(err, MessageError::NonFinite { .. }), "{err}");
    let clean = recordable_quality(e.data_quality.as_ref().unwrap());
    assert!(clean.warmup.is_none());
    assert_eq!(clean.outliers.at_s.len(), n_at - 1);
    assert_eq!(clean.outliers.excess_kurtosis, None);
    assert_eq!(
        clean.outliers.count,
        e.data_quality.as_ref().unwrap().outliers.count
    );
    e.data_quality = Some(clean);
    assert_eq!(SinkMessage::Estimates(e).validate(), Ok(()));
}

#[test]
fn validator_rejects_broken_messages() {
    // The checker above must be able to fail: remove each required field, change types.
    let m = SinkMessage::Raw(RawBatch {
        t0_ns: 1,
        dt_ns: 2,
        seq0: 3,
        counts: vec![1, -2],
        gaps: vec![Gap { index: 1, lost: 2 }],
        temp_c: None,
        status: 0,
    });
    let schema = Topic::Raw.json_schema();
    let good = json_of(&m);
    check(&schema, &good, "$").expect("good message");
    for key in good.as_object().unwrap().keys() {
        let mut bad = good.clone();
        bad.as_object_mut().unwrap().remove(key);
        assert!(check(&schema, &bad, "$").is_err(), "missing {key} accepted");
    }
    for (key, value) in [
        ("counts", json!("1,2")),
        ("counts", json!([1.5])),
        ("t0_ns", json!(-1)),
        ("temp_c", json!("hot")),
        ("gaps", json!([{"index": 0}])),
        ("gaps", json!([{"index": 0, "lost": 0}])),
        ("extra", json!(1)),
    ] {
        let mut bad = good.clone();
        bad[key] = value.clone();
        assert!(
            check(&schema, &bad, "$").is_err(),
            "{key} = {value} accepted"
        );
    }
    let ev = Topic::Events.json_schema();
    assert!(
        check(
            &ev,
            &json!({"t_ns": 1, "kind": "crc_error", "byte_offset": 3}),
            "$"
        )
        .is_ok()
    );
    assert!(check(&ev, &json!({"t_ns": 1, "kind": "crc_error"}), "$").is_err());
    assert!(
        check(
            &ev,
            &json!({"t_ns": 1, "kind": "meteor", "byte_offset": 3}),
            "$"
        )
        .is_err()
    );
    assert!(
        check(
            &ev,
            &json!({"t_ns": 1, "kind": "gap", "byte_offset": 3}),
            "$"
        )
        .is_err()
    );
    let est = Topic::Estimates.json_schema();
    // the shape of `sagnac analyze --json`'s `estimates`: value and ci95, or null and upper95
    let c = json!({"value": 1.0, "ci95": [0.5, 2.0]});
    let u = json!({"value": null, "upper95": 2.0});
    let e = json!({"t_ns": 1, "samples": 2, "duration_s": 0.5,
                   "estimates": {"quantization_arcsec": c, "arw_dpsh": u, "bias_instability_dph": c,
                                 "rrw_dphsh": u, "rate_ramp_dphh": u}});
    check(&est, &e, "$").unwrap();
    for (path, value) in [
        ("quantization_arcsec", json!({"value": "1"})),
        ("quantization_arcsec", json!({"value": 1.0, "lo95": 0.5})),
        ("arw_dpsh", json!({"upper95": 2.0})),
    ] {
        let mut bad = e.clone();
        bad["estimates"][path] = value.clone();
        assert!(check(&est, &bad, "$").is_err(), "{path} = {value} accepted");
    }
    let mut bad = e.clone();
    bad["estimates"]
        .as_object_mut()
        .unwrap()
        .remove("rate_ramp_dphh");
    assert!(check(&est, &bad, "$").is_err(), "a coefficient missing");
    let mut bad = e.clone();
    bad["estimates"]["qn_arcsec"] = c.clone();
    assert!(check(&est, &bad, "$").is_err(), "another name for Q");
    // /gyro/summary: Foxglove's {sec, nsec} and scalars
    let sum = Topic::Summary.json_schema();
    let s = json!({"timestamp": {"sec": 1, "nsec": 5}, "samples": 100, "lost_samples": 0,
                   "raw_rate_dph": 12.1, "clean_rate_dph": 12.3, "temp_c": null});
    check(&sum, &s, "$").unwrap();
    for (key, value) in [
        ("timestamp", json!(5)),
        ("timestamp", json!({"sec": 1})),
        ("raw_rate_dph", json!([1.0])),
    ] {
        let mut bad = s.clone();
        bad[key] = value.clone();
        assert!(check(&sum, &bad, "$").is_err(), "{key} = {value} accepted");
    }
}

#[test]
fn json_round_trip_is_exact() {
    // float_roundtrip: every f64 (random mantissas, exponents 1e-12..1e12) survives,
    // except the rate values, which come back on the 1e-3 deg/h grid.
    for m in sink::stream(12, 3000) {
        let back = SinkMessage::from_json(m.topic(), &m.to_json().unwrap()).expect("decode");
        assert_eq!(back, m.recorded());
    }
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let mut values: Vec<f64> = (0..20_000).map(|_| sink::awkward_f64(&mut rng)).collect();
    values.extend([f64::MIN_POSITIVE, 5e-324, f64::MAX, -0.0, 0.1 + 0.2, 1e-300]);
    values.extend([2.25e12, -2.26e12, 1e13, 1e15, 0.5e-3, 1.5e-3, -2.5e-3]);
    let m = SinkMessage::Clean(RateBatch {
        t0_ns: u64::MAX,
        dt_ns: 1,
        values,
    });
    for json in [m.to_json().unwrap(), {
        let mut b = Vec::new();
        m.write_json(&mut b).unwrap();
        b
    }] {
        let back = SinkMessage::from_json(Topic::Clean, &json).unwrap();
        match (&back, &m) {
            (SinkMessage::Clean(a), SinkMessage::Clean(b)) => {
                for (x, y) in a.values.iter().zip(&b.values) {
                    assert_eq!(x.to_bits(), quantize_rate(*y).to_bits(), "{x} vs {y}");
                    if y.abs() < 2.25e12 {
                        // the documented resolution: within 0.5e-3 deg/h (plus the
                        // rounding of y * 1e3 and of the decimal read back)
                        assert!((x - y).abs() <= 0.5e-3 * (1.0 + 1e-9) + y.abs() * 1e-15);
                        assert_eq!(quantize_rate(*x).to_bits(), x.to_bits(), "{x} on the grid");
                    } else {
                        assert_eq!(x.to_bits(), y.to_bits(), "{x} vs {y}: exact");
                    }
                }
            }
            _ => unreachable!(),
        }
    }
}

#[test]
fn rates_are_written_with_three_decimals() {
    let m = SinkMessage::Noise(RateBatch {
        t0_ns: 5,
        dt_ns: 1_000_000,
        values: vec![
            1.5,
            -0.0,
            0.0,
            -0.4e-3,
            -0.7e-3,
            1234.5678904,
            -1234.5676,
            1e-4,
            7e12,
            -1e300,
            2_251_799_813_685.247,
        ],
    });
    let mut b = Vec::new();
    m.write_json(&mut b).unwrap();
    assert_eq!(
        String::from_utf8(b).unwrap(),
        "{\"t0_ns\":5,\"dt_ns\":1000000,\"values\":[1.500,0.000,0.000,0.000,\
         -0.001,1234.568,-1234.568,0.000,7000000000000.0,-1e+300,\
         2251799813685.247]}"
    );
}

#[test]
fn recorder_json_equals_serde_json() {
    // The recorder's direct formatting of the sample batches (write_json) against
    // serde_json (to_json) on every message kind, awkward floats, negative and
    // extreme counts, gaps, absent temperature, empty batches; exact bytes (for
    // rate batches: equal JSON values, see rates_are_written_with_three_decimals).
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let mut msgs = sink::stream(21, 3000);
    let mut values: Vec<f64> = (0..5_000).map(|_| sink::awkward_f64(&mut rng)).collect();
    values.extend([
        f64::MIN_POSITIVE,
        5e-324,
        f64::MAX,
        -0.0,
        0.0,
        1.0,
        -3.0,
        1e21,
        1e-7,
    ]);
    msgs.push(SinkMessage::Noise(RateBatch {
        t0_ns: u64::MAX,
        dt_ns: 1,
        values,
    }));
    msgs.push(SinkMessage::Clean(RateBatch {
        t0_ns: 0,
        dt_ns: 0,
        values: vec![],
    }));
    msgs.push(SinkMessage::Raw(RawBatch {
        t0_ns: 1,
        dt_ns: 1_000_000,
        seq0: u64::MAX,
        counts: vec![i64::MIN, -1, 0, 1, i64::MAX],
        gaps: vec![
            Gap { index: 0, lost: 1 },
            Gap {
                index: 5,
                lost: u64::MAX,
            },
        ],
        temp_c: None,
        status: u32::MAX,
    }));
    msgs.push(SinkMessage::Raw(RawBatch {
        t0_ns: 0,
        dt_ns: 0,
        seq0: 0,
        counts: vec![],
        gaps: vec![],
        temp_c: Some(-0.0),
        status: 0,
    }));
    let mut buf = b"stale".to_vec();
    let mut kinds = std::collections::BTreeSet::new();
    for m in &msgs {
        m.write_json(&mut buf).unwrap();
        match m {
            // rates: three fixed decimals where serde_json writes the shortest form
            // of the same value on the 1e-3 deg/h grid: equal as JSON values
            SinkMessage::Clean(_) | SinkMessage::Noise(_) => {
                let a: Value = serde_json::from_slice(&buf).unwrap();
                let b: Value = serde_json::from_slice(&m.to_json().unwrap()).unwrap();
                assert_eq!(a, b, "{:?}", m.topic());
                let back = SinkMessage::from_json(m.topic(), &buf).unwrap();
                assert_eq!(back, m.recorded());
            }
            _ => assert_eq!(
                String::from_utf8_lossy(&buf),
                String::from_utf8_lossy(&m.to_json().unwrap()),
                "{:?}",
                m.topic()
            ),
        }
        kinds.insert(m.topic());
    }
    assert_eq!(kinds.len(), Topic::ALL.len());
}

#[test]
fn event_json_shape() {
    let e = SinkMessage::Event(Event {
        t_ns: 5,
        kind: EventKind::CrcError { byte_offset: 7 },
        gyro: None,
    });
    assert_eq!(
        String::from_utf8(e.to_json().unwrap()).unwrap(),
        r#"{"t_ns":5,"kind":"crc_error","byte_offset":7}"#
    );
    let d = SinkMessage::Event(Event {
        t_ns: 1,
        kind: EventKind::BackpressureDrop {
            sink: "mcap".into(),
            dropped: 3,
        },
        gyro: None,
    });
    assert_eq!(
        String::from_utf8(d.to_json().unwrap()).unwrap(),
        r#"{"t_ns":1,"kind":"backpressure_drop","sink":"mcap","dropped":3}"#
    );
    // Unknown kinds and fields are decode errors naming the topic, not panics.
    for bad in [
        r#"{"t_ns":5,"kind":"meteor"}"#,
        r#"{"t_ns":5,"kind":"crc_error"}"#,
        r#"{"kind":"crc_error","byte_offset":7}"#,
        r#"[1,2]"#,
        r#"{"t_ns":5,"kind":"crc_error","byte_offset":-7}"#,
        r#"{"t_ns":5,"kind":"crc_error","byte_offset":7,"extra":1}"#,
    ] {
        let err = SinkMessage::from_json(Topic::Events, bad.as_bytes()).unwrap_err();
        assert!(
            matches!(
                err,
                MessageError::Decode {
                    topic: "/gyro/events",
                    ..
                }
            ),
            "{bad}: {err}"
        );
    }
    let err = SinkMessage::from_json(Topic::Raw, br#"{"t0_ns":1}"#).unwrap_err();
    assert!(err.to_string().contains("/gyro/raw"), "{err}");
    // RawBatch refuses unknown fields (deny_unknown_fields).
    let err = SinkMessage::from_json(
        Topic::Clean,
        br#"{"t0_ns":1,"dt_ns":1,"values":[],"unit":"dph"}"#,
    )
    .unwrap_err();
    assert!(err.to_string().contains("unit"), "{err}");
}

#[test]
fn unrecordable_messages_are_refused() {
    let raw = |gaps: Vec<Gap>, dt_ns, temp_c| {
        SinkMessage::Raw(RawBatch {
            t0_ns: 0,
            dt_ns,
            seq0: 0,
            counts: vec![1, 2, 3],
            gaps,
            temp_c,
            status: 0,
        })
    };
    assert_eq!(
        raw(vec![Gap { index: 3, lost: 1 }], 1, Some(20.0)).validate(),
        Ok(())
    );
    assert!(matches!(
        raw(vec![], 1, Some(f64::NAN)).validate(),
        Err(MessageError::NonFinite { .. })
    ));
    assert!(matches!(
        raw(vec![Gap { index: 4, lost: 1 }], 1, None).validate(),
        Err(MessageError::BadGapIndex {
            index: 4,
            len: 3,
            ..
        })
    ));
    assert!(matches!(
        raw(
            vec![Gap { index: 2, lost: 1 }, Gap { index: 2, lost: 1 }],
            1,
            None
        )
        .validate(),
        Err(MessageError::BadGapIndex {
            gap: 1,
            previous: Some(2),
            ..
        })
    ));
    assert!(matches!(
        raw(vec![Gap { index: 0, lost: 0 }], 1, None).validate(),
        Err(MessageError::EmptyGap { .. })
    ));
    assert!(matches!(
        raw(vec![], 0, None).validate(),
        Err(MessageError::ZeroPeriod { .. })
    ));
    let rate = SinkMessage::Noise(RateBatch {
        t0_ns: 0,
        dt_ns: 1,
        values: vec![1.0, f64::INFINITY],
    });
    let err = rate.validate().unwrap_err();
    assert_eq!(
        err.to_string(),
        "/gyro/noise: field `values[1]` holds a non-finite number (inf)"
    );
    let ragged = SinkMessage::Allan(AllanUpdate::new(
        0,
        [(
            "raw".to_string(),
            AllanCurve {
                tau_s: vec![1.0, 2.0],
                dev: vec![1.0, 2.0],
                ci_lo: vec![1.0],
                ci_hi: vec![1.0, 2.0],
                n: vec![1, 2],
            },
        )]
        .into(),
    ));
    assert!(matches!(
        ragged.validate(),
        Err(MessageError::RaggedCurve { ci_lo: 1, .. })
    ));
    // The reader applies the same checks: a gap past the end does not decode.
    let bad = br#"{"t0_ns":1,"dt_ns":1,"seq0":0,"counts":[1],"gaps":[{"index":2,"lost":1}],"temp_c":null,"status":0}"#;
    assert!(SinkMessage::from_json(Topic::Raw, bad).is_err());
}

#[test]
fn topics_and_times() {
    let names: Vec<&str> = Topic::ALL.iter().map(|t| t.name()).collect();
    assert_eq!(
        names,
        [
            "/gyro/raw",
            "/gyro/clean",
            "/gyro/noise",
            "/gyro/estimates",
            "/gyro/allan",
            "/gyro/events",
            "/gyro/verdict",
            "/gyro/summary"
        ]
    );
    for t in Topic::ALL {
        assert_eq!(Topic::from_name(t.name()), Some(t));
    }
    assert_eq!(Topic::from_name("/gyro/other"), None);
    for m in sink::stream(14, 16) {
        let j = json_of(&m);
        // /gyro/summary states its time as Foxglove does: {sec, nsec}
        let foxglove = j.get("timestamp").map(|ts| {
            let nsec = ts["nsec"].as_u64().unwrap();
            assert!(nsec < 1_000_000_000);
            ts["sec"].as_u64().unwrap() * 1_000_000_000 + nsec
        });
        let t = j
            .get("t0_ns")
            .or(j.get("t_ns"))
            .and_then(Value::as_u64)
            .or(foxglove)
            .unwrap();
        assert_eq!(m.time_ns(), t);
    }
}

/// One name per quantity: `/gyro/estimates` carries the five coefficients under
/// the keys of `sagnac analyze --json` (the same `Coefficient` serialization:
/// `value` with `ci95`, or `null` with `upper95`), and its schema states the unit
/// of each.
#[test]
fn estimates_use_analyzes_names_and_the_schema_states_units() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let m = sink::estimate(&mut rng, 0);
    let j = json_of(&SinkMessage::Estimates(m.clone()));
    assert_eq!(
        j["estimates"],
        serde_json::to_value(m.estimates).unwrap(),
        "analyze's serialization"
    );
    let schema = Topic::Estimates.json_schema();
    let props = &schema["properties"]["estimates"]["properties"];
    assert_eq!(props.as_object().unwrap().len(), 5);
    for (key, unit, _) in sagnac::units::COEFFICIENTS {
        let d = props[key]["description"]
            .as_str()
            .unwrap_or_else(|| panic!("{key} in the schema"));
        assert!(d.contains(unit), "{key}: {d}");
        assert!(j["estimates"].get(key).is_some(), "{key} in the message");
        for field in ["ci95", "upper95"] {
            assert!(
                props[key]["properties"][field]["description"]
                    .as_str()
                    .unwrap()
                    .contains(unit),
                "{key}.{field}"
            );
        }
    }
    let summary = Topic::Summary.json_schema();
    for (field, unit) in [
        ("raw_rate_dph", "deg/h"),
        ("clean_rate_dph", "deg/h"),
        ("temp_c", "deg C"),
    ] {
        assert!(
            summary["properties"][field]["description"]
                .as_str()
                .unwrap()
                .contains(unit),
            "{field}"
        );
    }
}
