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

}  // namespace hwr::recon
