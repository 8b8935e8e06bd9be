#include "debug/draw_medial.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace strata {

namespace {

/// Field value at a point by the nearest node; +infinity outside the window.
double sample(const DistanceField& f, Vec2 p) {
    const double fi = (p.x - f.origin_x) / DistanceField::kCellPx;
    const double fj = (p.y - f.origin_y) / DistanceField::kCellPx;
    const long i = std::lround(fi);
    const long j = std::lround(fj);
    if (i < 0 || j < 0 || i >= long(f.nx) || j >= long(f.ny)) {
        return std::numeric_limits<double>::infinity();
    }
    return f.at(static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(j));
}

void draw_contours(RgbImage& image,
                   const SliceContourSet& set,
                   const DebugView& view,
                   ColorSrgb8 color) {
    for (const Contour& c : set.contours) {
        for (std::size_t i = 0; i < c.points.size(); ++i) {
            image.line(view.to_canvas(c.points[i]),
                       view.to_canvas(c.points[(i + 1) % c.points.size()]), color);
        }
    }
}

}  // namespace

RgbImage draw_medial_axis(const SliceContourSet& lower,
                          const SliceContourSet& upper,
                          const SliceDistanceFields& lower_fields,
                          const SliceDistanceFields& upper_fields,
                          const MedialAxis& axis,
                          const DebugView& view,
                          int correspondence_step) {
    RgbImage image(view.width * view.scale, view.height * view.scale);
    // summed field per canvas pixel: the smallest sum over labels present on both slices
    for (std::uint32_t y = 0; y < image.height; ++y) {
        for (std::uint32_t x = 0; x < image.width; ++x) {
            const Vec2 p{view.x0 + (x + 0.5) / view.scale, view.y0 + (y + 0.5) / view.scale};
            double best = std::numeric_limits<double>::infinity();
            for (const DistanceField& a : lower_fields.fields) {
                for (const DistanceField& b : upper_fields.fields) {
                    if (a.label == b.label) {
                        best = std::min(best, sample(a, p) + sample(b, p));
                    }
                }
            }
            if (!std::isfinite(best)) {
                continue;
            }
            const double magnitude = std::min(std::abs(best) / 40.0, 1.0);
            const bool band = std::fmod(std::abs(best), 4.0) < 2.0;
            const double shade = (band ? 0.8 : 1.0) * (0.25 + 0.75 * magnitude);
            const auto level = static_cast<std::uint8_t>(255 * shade);
            image.set(x, y,
                      best < 0 ? ColorSrgb8{0, static_cast<std::uint8_t>(level / 3), level}
                               : ColorSrgb8{level, static_cast<std::uint8_t>(level / 4), 0});
        }
    }
    draw_contours(image, lower, view, {255, 230, 0});
    draw_contours(image, upper, view, {0, 230, 255});
    for (const MedialCurve& curve : axis.curves) {
        const std::size_t n = curve.points.size();
        for (std::size_t i = 0; i < n; ++i) {
            const MedialPoint& m = curve.points[i];
            if (correspondence_step > 0 && i % correspondence_step == 0) {
                image.line(view.to_canvas(m.position),
                           view.to_canvas(site_position(lower, m.lower)), {60, 255, 60});
                image.line(view.to_canvas(m.position),
                           view.to_canvas(site_position(upper, m.upper)), {255, 60, 255});
            }
        }
        for (std::size_t i = 0; i < n; ++i) {
            image.line(view.to_canvas(curve.points[i].position),
                       view.to_canvas(curve.points[(i + 1) % n].position), {255, 255, 255});
        }
    }
    return image;
}

}  // namespace strata
