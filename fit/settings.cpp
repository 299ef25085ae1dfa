// FitSettings from the user's words: --model and --ablate.
#include <algorithm>
#include <stdexcept>

#include "stf/fit/fit_settings.h"

namespace stf::fit {

FitSettings parse_model_spec(const std::string& spec) {
  const std::string allowed =
      "--model must be auto, vmf:K, hvmf:K or lvmf:K (1..16), vmf:auto, hvmf:auto, lvmf:auto, sh:L (0..32) or sh:auto, got '" +
      spec + "'";
  if (spec == "auto") return parse_model_spec("hvmf:auto");
  auto colon = spec.find(':');
  if (colon == std::string::npos) throw std::invalid_argument(allowed);
  std::string kind = spec.substr(0, colon), size = spec.substr(colon + 1);
  FitSettings s;
  s.hemispherical = kind == "hvmf";
  s.lifted = kind == "lvmf";
  if (kind == "vmf" || kind == "hvmf" || kind == "lvmf") s.kind = ModelKind::kVmf;
  else if (kind == "sh") s.kind = ModelKind::kSh;
  else throw std::invalid_argument(allowed);
  if (size == "auto") {
    s.automatic = true;
    return s;
  }
  if (size.empty() || size.find_first_not_of("0123456789") != std::string::npos || size.size() > 3)
    throw std::invalid_argument(allowed);
  s.size = std::stoi(size);
  if ((s.kind == ModelKind::kVmf && (s.size < 1 || s.size > 16)) || (s.kind == ModelKind::kSh && s.size > 32))
    throw std::invalid_argument(allowed);
  return s;
}

void ablate(FitSettings& s, const std::string& list) {
  std::string allowed;
  for (const Ablation& a : kAblations) allowed += std::string(allowed.empty() ? "" : ", ") + a.name;
  for (std::size_t at = 0; at <= list.size();) {
    const std::size_t comma = std::min(list.find(',', at), list.size());
    const std::string name = list.substr(at, comma - at);
    at = comma + 1;
    const auto known = std::find_if(std::begin(kAblations), std::end(kAblations),
                                    [&](const Ablation& a) { return name == a.name; });
    if (known == std::end(kAblations))
      throw std::invalid_argument("--ablate takes a comma-separated list of " + allowed + ", got '" + name + "'");
    known->off(s);
  }
}

std::vector<int> auto_candidates(ModelKind kind) {
  return kind == ModelKind::kVmf ? std::vector<int>{1, 2, 3, 4, 6, 8, 12, 14} : std::vector<int>{2, 4, 6, 8, 12, 16};
}

}  // namespace stf::fit
