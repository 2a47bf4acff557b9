#pragma once
// Pressure read-out and metrics (pressure.md): one include for the pipeline and the CLI.
//
//   HandTemplate t = HandTemplate::load(default_template_path());   // t.synthetic(): say so to the user
//   PressureRenderer r(t, 256);                 // V, A, ridge inverse; r.warnings() for sensors outside V
//   Tensor proto = r.prototype_image();         // [1, 3, S, S] for the CLIP image tower
//   auto f = r.process_frame(Y + k * 3 * S * S); // generated frame -> H_raw, H_norm, H_std, p̂ (normalised)
//   newtons = kPressureMax * f.p;               // taxels in N; write_taxel_csv(path, seq)
//   paint_heatmap(f.h_norm, S, r.outline_canvas(), {.order = ChannelOrder::BGR});  // PNG-ready bytes
//   MetricAccumulator / evaluate_taxel_files for the metrics.
#include "pressure/evaluation.h"
#include "pressure/hand_template.h"
#include "pressure/heatmap_image.h"
#include "pressure/metrics.h"
#include "pressure/normalization.h"
#include "pressure/renderer.h"
#include "pressure/taxel_csv.h"
