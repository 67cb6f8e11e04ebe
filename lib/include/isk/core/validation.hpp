// The result of a validate() step: either fine, or the reason it is not.
//
// Jobs and builders validate their inputs before they run (ozz-animation's
// style); a failed validation says what is wrong in words a user can act on.
#pragma once

#include <string>
#include <utility>

namespace isk {

// Ok, or failed with a reason. Cheap to copy; never throws by itself.
class Validation {
 public:
  // Success.
  static Validation ok() { return Validation(); }
  // Failure with a reason naming what is wrong ("vertex 12: NaN weight").
  static Validation fail(std::string reason) {
    Validation v;
    v.ok_ = false;
    v.reason_ = std::move(reason);
    return v;
  }

  // True when ok.
  explicit operator bool() const { return ok_; }
  bool isOk() const { return ok_; }
  // Empty when isOk().
  const std::string& reason() const { return reason_; }

  // Throws isk::Error(kInvalidArgument) with `context: reason` when not ok.
  void throwIfFailed(const std::string& context) const;

 private:
  Validation() = default;
  bool ok_ = true;
  std::string reason_;
};

}  // namespace isk
