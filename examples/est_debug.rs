use sagnac::model::config::GyroModel;
use sagnac::model::sim::Simulator;
use sagnac::pipeline::{Pipeline, PipelineConfig, PipelineOutput};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let text = std::fs::read_to_string(&args[1]).unwrap();
    let model = GyroModel::from_toml_str(&text, "m").unwrap();
    let dur: f64 = args[2].parse().unwrap();
    let mut sim = Simulator::new(&model, 1, Some(dur)).unwrap();
    let mut p = Pipeline::new(&PipelineConfig::counts(1000.0, 1.21)).unwrap();
    let mut out = PipelineOutput::default();
    let mut c = Vec::new();
    loop { c.clear(); if sim.next_block(65536, &mut c) == 0 { break; } out.clear(); p.push_counts(&c, &mut out); }
    out.clear(); p.finish(&mut out);
    p.debug_levels();
    let a = p.analysis();
    println!("{}", serde_json::to_string_pretty(&a.estimates).unwrap());
}
