pub mod bake;
pub mod buffers;
pub mod dataset;
pub mod eval;
pub mod export_web;
pub mod realtime;
pub mod scene;
pub mod trace;
pub mod train;

/// A progress bar counting `{pos}/{len}` of what `label` names, and the `(done, total)` callback
/// the libraries report through.
pub fn counting_bar(label: &str) -> (indicatif::ProgressBar, impl Fn(u64, u64)) {
    let bar = indicatif::ProgressBar::new(0);
    let template = format!("{{spinner}} {label} {{pos}}/{{len}} [{{elapsed_precise}}] {{wide_bar}} ETA {{eta}}");
    bar.set_style(indicatif::ProgressStyle::with_template(&template).expect("a valid template").progress_chars("=> "));
    bar.enable_steady_tick(std::time::Duration::from_millis(250));
    let handle = bar.clone();
    (bar, move |done, total| {
        handle.set_length(total);
        handle.set_position(done);
    })
}
