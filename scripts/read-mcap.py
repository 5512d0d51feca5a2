#!/usr/bin/env python3
"""Independent reader of a sagnac MCAP recording (the Python `mcap` package, zstd
via `zstandard`); prints a JSON summary that tests/formats/sink_mcap.rs compares with what
the Rust recorder wrote.

Usage: scripts/read-mcap.py [--no-schema] [--summary] RECORDING.mcap
  --no-schema   skip the JSON Schema validation (slow on long recordings);
                schema_valid is then null
  --summary     also recompute the /gyro/summary windows from /gyro/raw and
                /gyro/clean (keys summary_recorded and summary_expected)

Summary keys:
  messages              total messages (indexed read, file order)
  channels              topic -> message count
  encodings             topic -> [message_encoding, schema_name, schema_encoding]
  statistics_messages   message count of the Statistics record (summary section)
  raw_samples           number of counts on /gyro/raw
  raw_counts_total      sum of all counts on /gyro/raw
  raw_lost_total        sum of gap "lost" on /gyro/raw
  values_total          topic -> number of values on /gyro/clean and /gyro/noise
  gyros                 a recording of several gyros: label -> raw_samples,
                        raw_counts_total, raw_lost_total, values_total
                        (clean/noise), events_by_kind (events naming the gyro),
                        last_estimates
  events_by_kind        kind -> count on /gyro/events
  time_mismatches       messages whose log_time or publish_time differs from the
                        payload time (t0_ns, t_ns, or timestamp {sec, nsec})
  schema_valid          messages valid against their channel's JSON Schema, checked
                        with the `jsonschema` package, or null when it is missing
  schema_invalid        list of the first validation errors (empty when valid)
  last_estimates        payload of the /gyro/estimates message with the largest
                        log time (the final estimates of a `sagnac run`), or null
  gap_lost_total        sum of "lost" over the gap events on /gyro/events
  metadata              name -> key-value map of each Metadata record (the
                        `sagnac` record: sample_rate_hz, output, pulse_arcsec,
                        model or config, sagnac_version), read through the
                        summary's metadata index
  summary_recorded      (--summary) the /gyro/summary messages in log-time order,
                        each [t_ns, samples, lost_samples, raw_rate_dph,
                        clean_rate_dph, temp_c]
  summary_expected      (--summary) the same windows recomputed here: the raw
                        counts with each gap's pulses spread over its periods as
                        integers (floor(I*(j+1)/n) - floor(I*j/n)), cut into
                        windows of round(sample_rate_hz * 0.1) periods from the
                        first sample, the raw mean times pulse_arcsec *
                        sample_rate_hz (deg/h), the clean mean of /gyro/clean
                        (recorded to 1e-3 deg/h); temp_c is [min, max] of the
                        raw batches' temperatures. Assumes one time segment
                        (sample times uniform from the first sample).
"""

import json
import sys

from mcap.reader import make_reader

try:
    import jsonschema  # optional: validation is reported as null without it
except ImportError:  # pragma: no cover
    jsonschema = None


def payload_time(payload):
    """The time a message states: t0_ns, t_ns, or Foxglove's {sec, nsec}."""
    if "timestamp" in payload:
        ts = payload["timestamp"]
        return ts["sec"] * 1_000_000_000 + ts["nsec"]
    return payload.get("t0_ns", payload.get("t_ns"))


def spread(total, n):
    """The integer shares of a gap sample's increment over its n periods."""
    return [(total * (j + 1)) // n - (total * j) // n for j in range(n)]


def expected_summary(raw, clean, metadata):
    """The /gyro/summary windows recomputed from the raw and clean channels."""
    meta = metadata.get("sagnac", {})
    rate_hz = float(meta["sample_rate_hz"])
    pulse = float(meta.get("pulse_arcsec", "1"))
    window = max(1, round(rate_hz * 0.1))
    periods, filled, temps = [], [], []
    raw.sort(key=lambda p: p["t0_ns"])
    t_first = raw[0]["t0_ns"] if raw else 0
    dt_ns = raw[0]["dt_ns"] if raw else 0
    for b in raw:
        lost_at = {g["index"]: g["lost"] for g in b["gaps"]}
        for i, c in enumerate(b["counts"]):
            n = lost_at.get(i, 0) + 1
            periods.extend(spread(c, n))
            filled.extend([True] * (n - 1) + [False])
        if b["temp_c"] is not None:
            temps.append(b["temp_c"])
    clean.sort(key=lambda p: p["t0_ns"])
    clean_values = [v for b in clean for v in b["values"]]
    out = []
    for a in range(0, len(periods), window):
        e = min(a + window, len(periods))
        n = e - a
        out.append([
            t_first + round(a * 1e9 / rate_hz) if dt_ns else 0,
            n,
            sum(filled[a:e]),
            sum(periods[a:e]) / n * pulse * rate_hz,
            sum(clean_values[a:e]) / n if e <= len(clean_values) else None,
            [min(temps), max(temps)] if temps else None,
        ])
    return out


def main() -> int:
    args = sys.argv[1:]
    check_schemas = "--no-schema" not in args
    want_summary = "--summary" in args
    args = [a for a in args if a not in ("--no-schema", "--summary")]
    if len(args) != 1:
        print(__doc__, file=sys.stderr)
        return 2
    path = args[0]
    channels: dict[str, int] = {}
    encodings: dict[str, list] = {}
    values_total: dict[str, int] = {}
    events_by_kind: dict[str, int] = {}
    raw_samples = raw_counts_total = raw_lost_total = 0
    time_mismatches = 0
    messages = 0
    validate = jsonschema is not None and check_schemas
    schema_valid = 0 if validate else None
    schema_invalid: list[str] = []
    validators: dict[int, object] = {}
    last_estimates = None
    last_estimates_time = -1
    gap_lost_total = 0
    raw_payloads, clean_payloads, summaries = [], [], []
    # a recording of several gyros: /gyro/<label>/<name> per gyro
    gyros: dict[str, dict] = {}

    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        statistics_messages = (
            summary.statistics.message_count
            if summary is not None and summary.statistics is not None
            else None
        )
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            messages += 1
            topic = channel.topic
            channels[topic] = channels.get(topic, 0) + 1
            encodings[topic] = [
                channel.message_encoding,
                schema.name if schema else None,
                schema.encoding if schema else None,
            ]
            payload = json.loads(message.data)
            t = payload_time(payload)
            if message.log_time != t or message.publish_time != t:
                time_mismatches += 1
            if want_summary and topic == "/gyro/raw":
                raw_payloads.append(payload)
            elif want_summary and topic == "/gyro/clean":
                clean_payloads.append(payload)
            elif want_summary and topic == "/gyro/summary":
                summaries.append(payload)
            parts = topic.split("/")
            if len(parts) == 4 and parts[1] == "gyro":
                g = gyros.setdefault(parts[2], {
                    "raw_samples": 0, "raw_counts_total": 0, "raw_lost_total": 0,
                    "values_total": {}, "events_by_kind": {}, "last_estimates": None, "_t": -1,
                })
                name = parts[3]
                if name == "raw":
                    g["raw_samples"] += len(payload["counts"])
                    g["raw_counts_total"] += sum(payload["counts"])
                    g["raw_lost_total"] += sum(x["lost"] for x in payload["gaps"])
                elif name in ("clean", "noise"):
                    g["values_total"][name] = g["values_total"].get(name, 0) + len(payload["values"])
                elif name == "estimates" and message.log_time >= g["_t"]:
                    g["_t"] = message.log_time
                    g["last_estimates"] = payload
            if topic == "/gyro/events" and "gyro" in payload:
                g = gyros.setdefault(payload["gyro"], {
                    "raw_samples": 0, "raw_counts_total": 0, "raw_lost_total": 0,
                    "values_total": {}, "events_by_kind": {}, "last_estimates": None, "_t": -1,
                })
                k = payload["kind"]
                g["events_by_kind"][k] = g["events_by_kind"].get(k, 0) + 1
            if topic == "/gyro/raw":
                raw_samples += len(payload["counts"])
                raw_counts_total += sum(payload["counts"])
                raw_lost_total += sum(g["lost"] for g in payload["gaps"])
            elif topic in ("/gyro/clean", "/gyro/noise"):
                values_total[topic] = values_total.get(topic, 0) + len(payload["values"])
            elif topic == "/gyro/events":
                kind = payload["kind"]
                events_by_kind[kind] = events_by_kind.get(kind, 0) + 1
                if kind == "gap":
                    gap_lost_total += payload["lost"]
            elif topic == "/gyro/estimates":
                if message.log_time >= last_estimates_time:
                    last_estimates_time = message.log_time
                    last_estimates = payload
            if validate and schema is not None:
                if schema.id not in validators:
                    doc = json.loads(schema.data)
                    cls = jsonschema.validators.validator_for(doc)
                    cls.check_schema(doc)
                    validators[schema.id] = cls(doc)
                errors = list(validators[schema.id].iter_errors(payload))
                if errors:
                    if len(schema_invalid) < 10:
                        schema_invalid.append(f"{topic}: {errors[0].message}")
                else:
                    schema_valid += 1

    extra = {}
    if want_summary:
        summaries.sort(key=payload_time)
        extra["summary_recorded"] = [
            [payload_time(m), m["samples"], m["lost_samples"], m["raw_rate_dph"], m["clean_rate_dph"], m["temp_c"]]
            for m in summaries
        ]
        extra["summary_expected"] = expected_summary(raw_payloads, clean_payloads, metadata)
    print(
        json.dumps(
            {
                **extra,
                "messages": messages,
                "channels": channels,
                "encodings": encodings,
                "statistics_messages": statistics_messages,
                "raw_samples": raw_samples,
                "raw_counts_total": raw_counts_total,
                "raw_lost_total": raw_lost_total,
                "values_total": values_total,
                "events_by_kind": events_by_kind,
                "time_mismatches": time_mismatches,
                "schema_valid": schema_valid,
                "schema_invalid": schema_invalid,
                "last_estimates": last_estimates,
                "gap_lost_total": gap_lost_total,
                "metadata": metadata,
                "gyros": {k: {kk: vv for kk, vv in v.items() if kk != "_t"} for k, v in gyros.items()},
            },
            sort_keys=True,
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
