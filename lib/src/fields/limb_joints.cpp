#include "isk/fields/limb_joints.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <string>

namespace isk {

std::vector<int> limbJoints(const Skeleton& skeleton,
                            const std::vector<int>& field_of_joint) {
  const int count = skeleton.jointCount();
  if (static_cast<int>(field_of_joint.size()) != count) return {};
  const TransformList globals = skeleton.bindGlobals();
  // The field tree: each joint with a field under its nearest ancestor with
  // one; roots of the tree have no parent there.
  std::vector<std::vector<int>> children(count);
  for (int j = 0; j < count; ++j) {
    if (field_of_joint[j] < 0) continue;
    int ancestor = skeleton.joints[j].parent;
    while (ancestor >= 0 && field_of_joint[ancestor] < 0)
      ancestor = skeleton.joints[ancestor].parent;
    if (ancestor < 0) continue;
    children[ancestor].push_back(j);
  }
  // Parents precede children, so one backward pass gives every subtree's
  // shape and summed bone length.
  std::vector<std::string> shape(count);
  std::vector<double> length(count, 0.0);
  for (int j = count - 1; j >= 0; --j) {
    std::vector<std::string> parts;
    for (int k : children[j]) {
      parts.push_back(shape[k]);
      length[j] +=
          length[k] + (globals[k].translation() - globals[j].translation())
                          .cast<double>()
                          .norm();
    }
    std::sort(parts.begin(), parts.end());
    shape[j] = "(";
    for (const std::string& p : parts) shape[j] += p;
    shape[j] += ")";
  }
  std::vector<char> limb(count, 0);
  for (int p = 0; p < count; ++p) {
    std::map<std::string, std::vector<int>> by_shape;
    for (int k : children[p]) by_shape[shape[k]].push_back(k);
    for (const auto& entry : by_shape) {
      const std::vector<int>& twins = entry.second;
      if (twins.size() != 2) continue;
      const double a = length[twins[0]], b = length[twins[1]];
      if (!(std::abs(a - b) <= kLimbLengthTolerance * std::max(a, b))) continue;
      for (int j : twins) {
        while (children[j].size() == 1) {
          j = children[j][0];
          limb[j] = 1;
        }
      }
    }
  }
  std::vector<int> out;
  for (int j = 0; j < count; ++j)
    if (limb[j]) out.push_back(j);
  return out;
}

}  // namespace isk
