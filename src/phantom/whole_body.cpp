// The whole-body-like benchmark map (whole_body.h): each class a few analytic primitives placed
// by hand from textbook anatomy, in px of 1 mm (z: mm above mid-thigh).

#include "phantom/whole_body.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <utility>

namespace strata {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
constexpr double kMid = 256.0;  // the body's midline, x

using Rotation = std::array<std::array<double, 3>, 3>;

/// Rotation by `about_z` around z after `about_x` around x (radians): Rz * Rx.
Rotation rotation(double about_z, double about_x = 0.0) {
    const double cz = std::cos(about_z), sz = std::sin(about_z);
    const double cx = std::cos(about_x), sx = std::sin(about_x);
    return {{{cz, -sz * cx, sz * sx}, {sz, cz * cx, -cz * sx}, {0.0, sx, cx}}};
}

Solid ellipsoid(Vec3 centre, Vec3 semi_axes, double about_z = 0.0, double about_x = 0.0) {
    return make_solid(Ellipsoid{centre, semi_axes, rotation(about_z, about_x)});
}

Solid ball(Vec3 centre, double radius) {
    return make_solid(Ball{centre, radius});
}

/// Capsules of `radius` along the polyline `points`.
Solid tube(const std::vector<Vec3>& points, double radius) {
    std::vector<Solid> parts;
    for (std::size_t i = 0; i + 1 < points.size(); ++i) {
        parts.push_back(make_solid(Capsule{points[i], points[i + 1], radius}));
    }
    return parts.size() == 1 ? std::move(parts[0]) : unite(std::move(parts));
}

Solid blobs(const std::vector<std::array<double, 5>>& centre_sigma_weight) {
    GaussianLevelSet g;
    g.level = 0.5;
    for (const auto& b : centre_sigma_weight) {
        g.blobs.push_back({{b[0], b[1], b[2]}, b[3], b[4]});
    }
    return make_solid(std::move(g));
}

/// The spine's centre line (vertebral bodies), y as a function of z: a gentle S.
double spine_y(double z) {
    return 300.0 + 10.0 * std::sin((z - 750.0) / 150.0);
}

struct Vertebra {
    const char* name;
    double z;            // centre, mm
    double half_height;  // of the body
    double rx, ry;       // body semi-axes
    double ring, minor;  // arch: torus around the canal
};

/// The 25 vertebrae S1, L5 ... L1, T12 ... T1, C7 ... C1 (labels 26 ... 50).
std::vector<Vertebra> vertebrae() {
    std::vector<Vertebra> v;
    v.push_back({"vertebrae_S1", 712, 11, 26, 18, 12, 4});
    const char* lumbar[] = {"vertebrae_L5", "vertebrae_L4", "vertebrae_L3", "vertebrae_L2",
                            "vertebrae_L1"};
    for (int i = 0; i < 5; ++i) {
        v.push_back({lumbar[i], 745.0 + 33.0 * i, 12, 23, 17, 11, 4});
    }
    const char* thoracic[] = {"vertebrae_T12", "vertebrae_T11", "vertebrae_T10", "vertebrae_T9",
                              "vertebrae_T8",  "vertebrae_T7",  "vertebrae_T6",  "vertebrae_T5",
                              "vertebrae_T4",  "vertebrae_T3",  "vertebrae_T2",  "vertebrae_T1"};
    for (int i = 0; i < 12; ++i) {
        v.push_back({thoracic[i], 908.0 + 23.0 * i, 9, 18, 14, 10, 3.5});
    }
    const char* cervical[] = {"vertebrae_C7", "vertebrae_C6", "vertebrae_C5", "vertebrae_C4",
                              "vertebrae_C3", "vertebrae_C2", "vertebrae_C1"};
    for (int i = 0; i < 7; ++i) {
        v.push_back({cervical[i], 1185.0 + 17.0 * i, 6, 12, 9, 9, 3});
    }
    return v;
}

/// A vertebra: body, arch (genus 1 with the body), spinous and transverse processes.
Solid vertebra(const Vertebra& v) {
    const double y = spine_y(v.z);
    const Vec3 body{kMid, y, v.z};
    const Vec3 canal{kMid, y + v.ry + v.ring - v.minor * 0.5, v.z};
    std::vector<Solid> parts;
    parts.push_back(ellipsoid(body, {v.rx, v.ry, v.half_height}));
    parts.push_back(make_solid(Torus{canal, {0, 0, 1}, v.ring, v.minor}));
    parts.push_back(
        make_solid(Capsule{canal + Vec3{0, v.ring, 0},
                           canal + Vec3{0, v.ring + 2.2 * v.rx, -0.8 * v.rx}, v.minor + 0.5}));
    for (double s : {-1.0, 1.0}) {
        parts.push_back(
            make_solid(Capsule{canal + Vec3{s * v.ring * 0.8, 0, 0},
                               canal + Vec3{s * (v.ring + 1.6 * v.rx), 4, 0}, v.minor}));
    }
    return unite(std::move(parts));
}

/// The canal centre of the spine at height z (for the cord).
Vec3 canal_at(double z, double ry, double ring, double minor) {
    return {kMid, spine_y(z) + ry + ring - minor * 0.5, z};
}

/// Rib `i` (1 ... 12) on side `s` (+1 left, -1 right): an arc around the thorax from the
/// transverse process forward and down; `end` receives its anterior end.
Solid rib(int i, double s, Vec3& end) {
    const double z0 = 1161.0 - 23.0 * (i - 1);
    const double ax = i <= 7 ? 75.0 + 65.0 * (i - 1) / 6.0 : 140.0 - 5.0 * (i - 7);
    const double ay = 62.0 + 38.0 * std::min(i - 1, 5) / 5.0;
    const double phi0 = 25.0 * kDeg;
    const double phi1 = (i <= 7 ? 160.0 : 160.0 - 14.0 * (i - 7)) * kDeg;
    std::vector<Vec3> points;
    constexpr int kSteps = 6;
    for (int t = 0; t <= kSteps; ++t) {
        const double f = double(t) / kSteps;
        const double phi = phi0 + (phi1 - phi0) * f;
        points.push_back(
            {kMid + s * ax * std::sin(phi), 250.0 + ay * std::cos(phi), z0 - 45.0 * f});
    }
    end = points.back();
    return tube(points, i == 1 ? 6.0 : 5.0);
}

// Sides: +x is the patient's left (LPS).
constexpr double kLeft = 1.0;
constexpr double kRight = -1.0;

std::string side(double s, const char* left, const char* right) {
    return std::string(s > 0 ? left : right);
}

/// Appends labelled solids to `out`, in paint order.
struct SolidList {
    std::vector<LabelledSolid>& out;
    void operator()(std::uint16_t label, std::string name, Solid solid) const {
        out.push_back({label, std::move(name), std::move(solid)});
    }
};

/// Muscles (first: organs and bones cover them where they meet) and the lungs' lobes.
void add_muscles_and_lungs(const SolidList& add) {
    // Muscles first: organs and bones cover them where they meet.
    for (double s : {kLeft, kRight}) {
        const std::uint16_t l = s > 0 ? 0 : 1;
        std::vector<Vec3> back;
        for (double z : {720.0, 860.0, 1000.0, 1140.0, 1250.0}) {
            back.push_back({kMid + s * 32.0, spine_y(z) + 42.0, z});
        }
        add(86 + l, side(s, "autochthon_left", "autochthon_right"), tube(back, 15.0));
        add(88 + l, side(s, "iliopsoas_left", "iliopsoas_right"),
            tube({{kMid + s * 42, spine_y(860) + 2, 860},
                  {kMid + s * 68, 292, 700},
                  {kMid + s * 88, 232, 600},
                  {kMid + s * 96, 248, 540}},
                 16.0));
        add(80 + l, side(s, "gluteus_maximus_left", "gluteus_maximus_right"),
            ellipsoid({kMid + s * 82, 372, 600}, {52, 28, 72}, s * 15 * kDeg, 10 * kDeg));
        add(82 + l, side(s, "gluteus_medius_left", "gluteus_medius_right"),
            ellipsoid({kMid + s * 126, 322, 690}, {28, 40, 48}, s * -20 * kDeg));
        add(84 + l, side(s, "gluteus_minimus_left", "gluteus_minimus_right"),
            ellipsoid({kMid + s * 118, 296, 662}, {16, 24, 30}, s * -20 * kDeg));
    }

    // Lungs, split into lobes by the oblique fissure (higher at the back) and, on the right,
    // the horizontal one.
    for (double s : {kLeft, kRight}) {
        const Solid lung = ellipsoid({kMid + s * 85, 245, 1030}, {60, 88, 138});
        // upper side of the oblique fissure z = 1030 + 0.6 (y - 245): -z + 0.6 y <= -883
        const Solid above_oblique = make_solid(HalfSpace{{0, 0.6, -1.0}, 0.6 * 245 - 1030});
        if (s > 0) {
            add(10, "lung_upper_lobe_left", intersect({lung, above_oblique}));
            add(11, "lung_lower_lobe_left", subtract(lung, above_oblique));
        } else {
            const Solid above_horizontal = make_solid(HalfSpace{{0, 0, -1.0}, -1075.0});
            add(12, "lung_upper_lobe_right", intersect({lung, above_oblique, above_horizontal}));
            add(13, "lung_middle_lobe_right",
                subtract(intersect({lung, above_oblique}), above_horizontal));
            add(14, "lung_lower_lobe_right", subtract(lung, above_oblique));
        }
    }
}

/// The abdominal, pelvic, neck and chest organs.
void add_organs(const SolidList& add) {
    // Abdominal and pelvic organs.
    add(5, "liver",
        blobs({{200, 232, 890, 42, 1.0},
               {242, 210, 902, 32, 0.8},
               {172, 262, 860, 32, 0.8},
               {282, 200, 912, 22, 0.6}}));
    add(4, "gallbladder", ellipsoid({214, 188, 846}, {13, 13, 27}, 20 * kDeg, 25 * kDeg));
    add(6, "stomach",
        blobs({{322, 215, 930, 26, 1.0}, {302, 198, 890, 23, 0.9}, {272, 204, 862, 17, 0.8}}));
    add(1, "spleen", ellipsoid({346, 302, 902}, {22, 45, 55}, -30 * kDeg));
    add(2, "kidney_right", ellipsoid({kMid - 70, 316, 820}, {24, 18, 50}, -20 * kDeg, 8 * kDeg));
    add(3, "kidney_left", ellipsoid({kMid + 70, 316, 835}, {24, 18, 50}, 20 * kDeg, 8 * kDeg));
    add(24, "kidney_cyst_right", ball({kMid - 90, 312, 800}, 8));
    add(23, "kidney_cyst_left", ball({kMid + 91, 318, 852}, 9));
    add(8, "adrenal_gland_right", ellipsoid({kMid - 56, 318, 884}, {12, 5, 17}, -40 * kDeg));
    add(9, "adrenal_gland_left", ellipsoid({kMid + 56, 314, 896}, {12, 5, 17}, 40 * kDeg));
    add(7, "pancreas",
        unite({tube({{262, 246, 845}, {300, 266, 855}, {340, 290, 870}}, 10.0),
               ball({246, 246, 835}, 17)}));
    add(19, "duodenum",
        tube({{236, 226, 862}, {214, 240, 840}, {214, 250, 800}, {246, 256, 790}, {276, 250, 806}},
             9.0));
    {
        // small bowel: a meander through the lower abdomen, six rows of loops
        std::vector<Vec3> path;
        for (int row = 0; row < 6; ++row) {
            const double z = 780.0 - 25.0 * row;
            const double y = row % 2 == 0 ? 190.0 : 230.0;
            for (int col = 0; col < 4; ++col) {
                const int c = row % 2 == 0 ? col : 3 - col;
                path.push_back({196.0 + 40.0 * c, y + (c % 2 == 0 ? 0.0 : 22.0), z});
            }
        }
        add(18, "small_bowel", tube(path, 9.0));
    }
    add(20, "colon",
        tube({{180, 222, 700},
              {175, 232, 830},
              {190, 190, 862},
              {256, 168, 852},
              {322, 190, 872},
              {344, 232, 882},
              {346, 242, 730},
              {320, 232, 680},
              {280, 252, 650},
              {256, 300, 620},
              {256, 312, 570}},
             16.0));
    add(21, "urinary_bladder", ellipsoid({kMid, 204, 610}, {38, 28, 28}));
    add(22, "prostate", ball({kMid, 238, 568}, 15));

    // Neck and chest organs.
    add(15, "esophagus",
        tube({{kMid, 268, 1280}, {258, 282, 1100}, {268, 270, 960}, {292, 232, 900}}, 7.0));
    add(16, "trachea",
        unite({tube({{kMid, 228, 1290}, {kMid, 246, 1080}}, 10.0),
               tube({{kMid, 246, 1080}, {214, 256, 1050}}, 7.0),
               tube({{kMid, 246, 1080}, {298, 256, 1050}}, 7.0)}));
    add(17, "thyroid_gland",
        unite({ellipsoid({kMid - 20, 222, 1225}, {8, 8, 22}),
               ellipsoid({kMid + 20, 222, 1225}, {8, 8, 22}),
               tube({{kMid - 18, 212, 1215}, {kMid + 18, 212, 1215}}, 5.0)}));
    add(51, "heart", ellipsoid({270, 205, 960}, {55, 45, 60}, 30 * kDeg, 20 * kDeg));
    add(61, "atrial_appendage_left", ball({316, 214, 992}, 12));
    add(53, "pulmonary_vein",
        unite({tube({{300, 252, 985}, {334, 264, 1002}}, 6.0),
               tube({{300, 252, 985}, {334, 264, 964}}, 6.0),
               tube({{232, 252, 985}, {196, 264, 1002}}, 6.0),
               tube({{232, 252, 985}, {196, 264, 964}}, 6.0)}));
}

/// The vessels, the spine and the cord.
void add_vessels_and_spine(const SolidList& add) {
    // Vessels.
    add(52, "aorta",
        tube({{262, 214, 965},
              {265, 208, 1080},
              {262, 234, 1116},
              {250, 274, 1102},
              {248, spine_y(1000) - 26, 1000},
              {250, spine_y(880) - 28, 880},
              {252, spine_y(760) - 30, 745}},
             11.0));
    add(54, "brachiocephalic_trunk", tube({{258, 226, 1114}, {236, 226, 1150}}, 7.0));
    add(55, "subclavian_artery_right",
        tube({{236, 226, 1150}, {190, 236, 1166}, {140, 242, 1160}}, 5.0));
    add(56, "subclavian_artery_left",
        tube({{250, 252, 1112}, {300, 246, 1160}, {366, 240, 1160}}, 5.0));
    add(57, "common_carotid_artery_right", tube({{236, 226, 1150}, {232, 236, 1300}}, 4.5));
    add(58, "common_carotid_artery_left", tube({{258, 240, 1114}, {278, 236, 1300}}, 4.5));
    add(59, "brachiocephalic_vein_left", tube({{340, 216, 1150}, {276, 206, 1120}}, 6.0));
    add(60, "brachiocephalic_vein_right", tube({{180, 216, 1150}, {240, 206, 1116}}, 7.0));
    add(62, "superior_vena_cava", tube({{242, 208, 1114}, {240, 214, 1000}}, 9.0));
    add(63, "inferior_vena_cava",
        tube({{238, spine_y(740) - 22, 720}, {235, 276, 870}, {240, 236, 934}}, 11.0));
    add(64, "portal_vein_and_splenic_vein",
        unite({tube({{230, 250, 850}, {276, 266, 830}, {330, 286, 840}}, 6.0),
               tube({{230, 250, 850}, {200, 236, 880}}, 7.0)}));
    const Vec3 aorta_end{252, spine_y(760) - 30, 745};
    const Vec3 cava_end{238, spine_y(740) - 22, 720};
    for (double s : {kLeft, kRight}) {
        const std::uint16_t l = s > 0 ? 0 : 1;
        add(65 + l, side(s, "iliac_artery_left", "iliac_artery_right"),
            tube({aorta_end, {kMid + s * 45, 262, 680}, {kMid + s * 80, 226, 600}}, 7.0));
        add(67 + l, side(s, "iliac_vena_left", "iliac_vena_right"),
            tube({cava_end, {kMid + s * 40, 276, 668}, {kMid + s * 78, 242, 595}}, 8.0));
    }

    // Spine and cord.
    {
        const std::vector<Vertebra> spine = vertebrae();
        std::vector<Vec3> cord;
        for (auto it = spine.rbegin(); it != spine.rend() && it->z >= 870.0; ++it) {
            cord.push_back(canal_at(it->z, it->ry, it->ring, it->minor));
        }
        add(79, "spinal_cord", tube(cord, 4.0));
        add(25, "sacrum", ellipsoid({kMid, spine_y(660) + 12, 660}, {40, 18, 45}, 0, 25 * kDeg));
        for (std::size_t i = 0; i < spine.size(); ++i) {
            add(static_cast<std::uint16_t>(26 + i), spine[i].name, vertebra(spine[i]));
        }
    }
}

/// Ribs, costal cartilages, sternum, shoulder girdle, arms; the skull around the brain.
void add_thorax_and_head(const SolidList& add) {
    // Thorax: ribs, costal cartilages, sternum, shoulder girdle, arms.
    {
        std::vector<Solid> cartilages;
        for (double s : {kLeft, kRight}) {
            for (int i = 1; i <= 12; ++i) {
                Vec3 end;
                Solid r = rib(i, s, end);
                const std::uint16_t label = static_cast<std::uint16_t>((s > 0 ? 91 : 103) + i);
                add(label, (s > 0 ? "rib_left_" : "rib_right_") + std::to_string(i), std::move(r));
                if (i <= 10) {
                    const double z = std::clamp(end.z - 10.0, 962.0, 1138.0);
                    cartilages.push_back(make_solid(Capsule{end, {kMid + s * 13, 152, z}, 4.0}));
                }
            }
        }
        add(117, "costal_cartilages", unite(std::move(cartilages)));
        add(116, "sternum", ellipsoid({kMid, 150, 1050}, {15, 7, 95}));
    }
    for (double s : {kLeft, kRight}) {
        const std::uint16_t l = s > 0 ? 0 : 1;
        add(73 + l, side(s, "clavicula_left", "clavicula_right"),
            tube({{kMid + s * 18, 160, 1160},
                  {kMid + s * 80, 175, 1176},
                  {kMid + s * 150, 215, 1180}},
                 7.0));
        add(71 + l, side(s, "scapula_left", "scapula_right"),
            unite({ellipsoid({kMid + s * 100, 346, 1090}, {45, 8, 65}, s * -25 * kDeg),
                   tube({{kMid + s * 66, 350, 1130}, {kMid + s * 150, 300, 1165}}, 6.0)}));
        add(69 + l, side(s, "humerus_left", "humerus_right"),
            unite({ball({kMid + s * 168, 266, 1150}, 22),
                   tube({{kMid + s * 172, 266, 1150}, {kMid + s * 185, 270, 860}}, 12.0),
                   ellipsoid({kMid + s * 187, 270, 850}, {25, 12, 12})}));
        // hip bone: the wing and the ring around the obturator foramen (genus 1)
        add(77 + l, side(s, "hip_left", "hip_right"),
            unite({ellipsoid({kMid + s * 95, 285, 690}, {18, 45, 58}, s * 30 * kDeg),
                   ellipsoid({kMid + s * 76, 292, 612}, {16, 24, 34}),
                   make_solid(Torus{{kMid + s * 70, 262, 596}, {1, 0, 0.3}, 16, 6})}));
        add(75 + l, side(s, "femur_left", "femur_right"),
            unite({ball({kMid + s * 98, 262, 640}, 23),
                   tube({{kMid + s * 98, 262, 640}, {kMid + s * 125, 270, 600}}, 14.0),
                   ball({kMid + s * 135, 276, 615}, 17),
                   tube({{kMid + s * 125, 270, 600}, {kMid + s * 105, 265, 20}}, 15.0)}));
    }

    // Head: the skull's shell around the brain.
    add(91, "skull",
        subtract(ellipsoid({kMid, 260, 1390}, {78, 95, 90}),
                 ellipsoid({kMid, 260, 1394}, {71, 88, 83})));
    add(90, "brain", ellipsoid({kMid, 260, 1395}, {67, 84, 77}));
}

}  // namespace

std::vector<LabelledSolid> whole_body_solids() {
    std::vector<LabelledSolid> out;
    const SolidList add{out};
    add_muscles_and_lungs(add);
    add_organs(add);
    add_vessels_and_spine(add);
    add_thorax_and_head(add);
    return out;
}

}  // namespace strata
