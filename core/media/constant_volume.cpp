#include "core/media/constant_volume.h"

#include <sstream>

namespace render {

ConstantVolume::ConstantVolume(const Rgb& value, bool grey)
    : value_(value), grey_(grey || (value.r == value.g && value.g == value.b)) {}

Aabb ConstantVolume::bounds() const {
    Aabb b;
    b.lo = Vec3(-kInfinity);
    b.hi = Vec3(kInfinity);
    return b;
}

std::string ConstantVolume::to_string() const {
    std::ostringstream os;
    os << "constvolume(" << value_ << ")";
    return os.str();
}

}  // namespace render
