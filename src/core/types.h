#pragma once

#include <array>
#include <cmath>
#include <cstdint>

namespace strata {

/// 2D point or vector; units are given by the owner (pixels inside the reconstruction stages).
struct Vec2 {
    double x = 0.0;
    double y = 0.0;

    friend Vec2 operator+(Vec2 a, Vec2 b) { return {a.x + b.x, a.y + b.y}; }
    friend Vec2 operator-(Vec2 a, Vec2 b) { return {a.x - b.x, a.y - b.y}; }
    friend Vec2 operator*(double s, Vec2 a) { return {s * a.x, s * a.y}; }
    friend bool operator==(Vec2 a, Vec2 b) = default;
};

/// 3D point or vector; units are given by the owner.
struct Vec3 {
    double x = 0.0;
    double y = 0.0;
    double z = 0.0;

    double& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
    double operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
    friend Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
    friend Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
    friend Vec3 operator*(double s, Vec3 a) { return {s * a.x, s * a.y, s * a.z}; }
    friend bool operator==(Vec3 a, Vec3 b) = default;
};

inline double dot(Vec2 a, Vec2 b) {
    return a.x * b.x + a.y * b.y;
}
inline double cross(Vec2 a, Vec2 b) {
    return a.x * b.y - a.y * b.x;
}
inline double dot(Vec3 a, Vec3 b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
inline Vec3 cross(Vec3 a, Vec3 b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double norm(Vec2 a) {
    return std::sqrt(dot(a, a));
}
inline double norm(Vec3 a) {
    return std::sqrt(dot(a, a));
}

/// Affine map of 3D points: p' = linear * p + translation. `linear` is row-major
/// (linear[r][c]); columns are the images of the unit axes.
struct Affine3 {
    std::array<std::array<double, 3>, 3> linear{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
    Vec3 translation{};

    Vec3 apply(Vec3 p) const {
        Vec3 r = translation;
        for (int i = 0; i < 3; ++i) {
            r[i] += linear[i][0] * p.x + linear[i][1] * p.y + linear[i][2] * p.z;
        }
        return r;
    }
    /// Column c of the linear part (the image of unit axis c).
    Vec3 column(int c) const { return {linear[0][c], linear[1][c], linear[2][c]}; }
    double determinant() const {
        const auto& m = linear;
        return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
               m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
               m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    }
};

/// An sRGB colour, 8 bits per channel, as colour tables store it.
using ColorSrgb8 = std::array<std::uint8_t, 3>;

}  // namespace strata
