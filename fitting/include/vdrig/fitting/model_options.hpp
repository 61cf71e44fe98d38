// The fit options of the models, each model's of its own type, held by MapFitOptions::model_options (fit_map.hpp) so
// that the map fit names no model: a model declares its options beside itself (PhongFitOptions in phong.hpp,
// ShFitOptions in sh.hpp, ...) and reads them with get<T>(); a caller sets them with edit<T>().
//
// An option type T is any default-constructible, copyable struct with `std::string fingerprint() const`: every
// field as text, equal text for equal options. The model's ReflectanceModel::options_fingerprint passes it on to
// fit_options_fingerprint (tiled_fit.hpp), which identifies restartable and distributed fits, and `vdrig fit`
// rejects a command-line option that does not change it ("does not apply to" the model).
#pragma once

#include <map>
#include <memory>
#include <typeindex>
#include <typeinfo>
#include <utility>

namespace vdrig::fitting {

class ModelOptions {
 public:
  /// The options of type T as set, or T's defaults when never set.
  template <class T>
  const T& get() const {
    const auto it = sets_.find(std::type_index(typeid(T)));
    if (it == sets_.end()) {
      static const T defaults{};
      return defaults;
    }
    return *static_cast<const T*>(it->second.get());
  }

  /// The options of type T to change (T's defaults when never set). Copies of a ModelOptions share their option sets
  /// until one of them edits a set (copy on write), so copying MapFitOptions stays cheap; not to be called while
  /// another thread copies this object.
  template <class T>
  T& edit() {
    std::shared_ptr<void>& slot = sets_[std::type_index(typeid(T))];
    if (!slot)
      slot = std::make_shared<T>();
    else if (slot.use_count() > 1)
      slot = std::make_shared<T>(*static_cast<const T*>(slot.get()));
    return *static_cast<T*>(slot.get());
  }

  template <class T>
  void set(T options) {
    sets_[std::type_index(typeid(T))] = std::make_shared<T>(std::move(options));
  }

 private:
  std::map<std::type_index, std::shared_ptr<void>> sets_;
};

}  // namespace vdrig::fitting
