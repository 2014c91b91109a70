// The points made from PROPS, kept per distinct PROPS array (its bits): an FE code passes the
// same PROPS at every integration point of a material, and making a point (its slip systems,
// its kernel phase) costs far more than a step. Shared by every thread; a point is read-only.
#pragma once

#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>

namespace subslip::fe {

template <class Material>
class MaterialCache {
 public:
  // The material of these PROPS, made by make(props, nprops) on first use. A make that throws
  // caches nothing (the next call with those PROPS tries again and throws again).
  template <class Make>
  std::shared_ptr<const Material> get(const double* props, int nprops, Make&& make) {
    std::string key(reinterpret_cast<const char*>(props),
                    sizeof(double) * static_cast<std::size_t>(nprops));
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      const auto it = materials_.find(key);
      if (it != materials_.end()) return it->second;
    }
    auto made = std::make_shared<const Material>(make(props, nprops));
    const std::lock_guard<std::mutex> lock(mutex_);
    // Two threads may have made it at once: the first stored wins, both are equal.
    return materials_.try_emplace(std::move(key), std::move(made)).first->second;
  }

 private:
  std::mutex mutex_;
  std::unordered_map<std::string, std::shared_ptr<const Material>> materials_;
};

}  // namespace subslip::fe
