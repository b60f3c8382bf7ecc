#include "hwr/recon/weld_region.hpp"

#include <algorithm>
#include <cstring>

namespace hwr::recon {

const char* weld_region_source_name(WeldRegionSource source) {
  switch (source) {
    case WeldRegionSource::kModel:
      return "model";
    case WeldRegionSource::kGeometry:
      return "geometry";
    case WeldRegionSource::kOperator:
      return "operator";
    case WeldRegionSource::kSimTruth:
      return "sim-truth";
  }
  return "unknown";
}

void set_weld_region_label(WeldRegion* region, const std::string& text) {
  region->label.fill('\0');
  const size_t n = std::min(text.size(), kWeldRegionLabelBytes - 1);
  std::memcpy(region->label.data(), text.data(), n);
}

std::string weld_region_label(const WeldRegion& region) {
  const auto end = std::find(region.label.begin(), region.label.end(), '\0');
  return std::string(region.label.begin(), end);
}

static_assert(static_cast<int>(detect::DetectionSource::kModel) ==
                      static_cast<int>(WeldRegionSource::kModel) &&
                  static_cast<int>(detect::DetectionSource::kGeometry) ==
                      static_cast<int>(WeldRegionSource::kGeometry) &&
                  static_cast<int>(detect::DetectionSource::kOperator) ==
                      static_cast<int>(WeldRegionSource::kOperator),
              "detection and weld-region sources share their numbers");

WeldRegion weld_region_from_detection(const detect::Detection& d) {
  WeldRegion w;
  w.source = static_cast<WeldRegionSource>(d.source);
  w.confidence = d.confidence;
  set_weld_region_label(&w, detect::seam_kind_name(d.kind));
  w.keyframe_id = d.keyframe_id;
  w.t_ns = d.t_ns;
  w.T_cam_region = d.T_cam_box;
  w.half_size_m = d.half_size_m;
  return w;
}

}  // namespace hwr::recon
