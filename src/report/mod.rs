//! Reports: SVG pictures (map, cells, path, histograms) and the latency/CPU
//! budget report.
