// Planar contour input: the RTSTRUCT and contour JSON readers, the cleaning of contours as
// planning systems write them, and bad DICOM answered with exit 2 and a clear message.

#include "input/planar_contours.h"

#include <cmath>
#include <cstdlib>
#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>
#include <fstream>
#include <functional>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "support/test_paths.h"

namespace strata {
namespace {

namespace fs = std::filesystem;

const fs::path kRtstruct = test::shared_data_dir() / "dicompyler_breast_rtstruct" / "rtss.dcm";
const fs::path kCt = test::shared_data_dir() / "dicompyler_breast_rtstruct" / "ct.0.dcm";
const fs::path kJson = test::shared_data_dir() / "dicompyler_breast_rtstruct" / "contours.json";

double polygon_area(const std::vector<Vec2>& p) {
    double a = 0.0;
    for (std::size_t i = 0; i < p.size(); ++i) {
        a += cross(p[i], p[(i + 1) % p.size()]);
    }
    return 0.5 * a;
}

bool has_warning(const Report& report, const std::string& where, const std::string& text) {
    for (const Warning& w : report.warnings) {
        if (w.where.find(where) != std::string::npos && w.message.find(text) != std::string::npos) {
            return true;
        }
    }
    return false;
}

TEST(PlanarContours, RtstructAndItsJsonGiveTheSameStructures) {
    // Two readers (DCMTK on the DICOM file, nlohmann_json on the JSON written from it by
    // dicompyler's authors' data) must agree on every ROI and point.
    const RawContourSet dicom = read_raw_contours(kRtstruct.string(), "");
    const RawContourSet json = read_raw_contours(kJson.string(), "");
    ASSERT_EQ(dicom.rois.size(), 10u);
    ASSERT_EQ(json.rois.size(), dicom.rois.size());
    ASSERT_TRUE(dicom.reference.has_value()) << "ct.0.dcm beside rtss.dcm shares its frame";
    EXPECT_NEAR(dicom.reference->pixel_mm[0], 1.074, 1e-3);
    EXPECT_EQ(dicom.reference->columns, 512u);
    for (std::size_t r = 0; r < dicom.rois.size(); ++r) {
        const RawRoi& a = dicom.rois[r];
        const RawRoi& b = json.rois[r];
        EXPECT_EQ(a.number, b.number);
        EXPECT_EQ(a.name, b.name);
        EXPECT_EQ(a.interpreted_type, b.interpreted_type);
        ASSERT_TRUE(a.color && b.color) << a.name;
        EXPECT_EQ(*a.color, *b.color) << a.name;
        ASSERT_EQ(a.contours.size(), b.contours.size()) << a.name;
        // note: the JSON groups contours by slice; match each DICOM contour by its first point
        for (const RawContour& c : a.contours) {
            const auto same =
                std::find_if(b.contours.begin(), b.contours.end(), [&](const RawContour& d) {
                    return d.points.size() == c.points.size() &&
                           norm(d.points[0] - c.points[0]) < 0.006;
                });
            ASSERT_NE(same, b.contours.end()) << c.where;
            for (std::size_t p = 0; p < c.points.size(); ++p) {
                EXPECT_LT(norm(same->points[p] - c.points[p]), 0.006) << c.where << " point " << p;
            }
        }
    }
}

TEST(PlanarContours, RtstructCleansToItsPlanesAndReportsTheEmptyRoi) {
    Report report;
    const PlanarContours contours =
        clean_planar_contours(read_raw_contours(kRtstruct.string(), ""), {}, report);
    ASSERT_EQ(contours.objects.size(), 10u);
    EXPECT_NEAR(contours.normal.z, 1.0, 1e-9);  // axial CT
    const ContourObject& areola = contours.objects[1];
    EXPECT_EQ(areola.name, "Areola");
    EXPECT_TRUE(areola.planes.empty());
    EXPECT_TRUE(has_warning(report, "ROI 2 (Areola)", "no contours"));
    const ContourObject& body = contours.objects[0];
    EXPECT_EQ(body.planes.size(), 98u);
    std::size_t contour_count = 0;
    for (const ContourPlane& plane : body.planes) {
        contour_count += plane.contours.size();
        // planes on the 3 mm CT raster through z = -122.44
        const double k = (plane.w + 122.44) / 3.0;
        EXPECT_NEAR(k, std::round(k), 1e-6);
    }
    EXPECT_EQ(contour_count, 141u);
}

RawContour square(double x0, double y0, double side, double z) {
    RawContour c;
    c.points = {{x0, y0, z}, {x0 + side, y0, z}, {x0 + side, y0 + side, z}, {x0, y0 + side, z}};
    c.where = "square";
    return c;
}

TEST(PlanarContours, CleaningRemovesRepeatsAndCollinearPointsWithoutChangingThePolygon) {
    RawContourSet raw;
    raw.source = "synthetic";
    RawRoi roi;
    roi.number = 7;
    RawContour c = square(0, 0, 10, 5);
    // a repeated point, a collinear midpoint, a nearly collinear one, and the closing point
    c.points.insert(c.points.begin() + 1, Vec3{0, 0, 5});
    c.points.insert(c.points.begin() + 2, Vec3{5, 0, 5});
    c.points.insert(c.points.begin() + 4, Vec3{10, 5.00000001, 5});
    c.points.push_back(Vec3{0, 0, 5});
    roi.contours.push_back(c);
    RawContour marker;
    marker.geometric_type = "POINT";
    marker.points = {{1, 2, 3}};
    roi.contours.push_back(marker);
    raw.rois.push_back(roi);
    Report report;
    const PlanarContours out = clean_planar_contours(raw, {}, report);
    ASSERT_EQ(out.objects.size(), 1u);
    const ContourObject& o = out.objects[0];
    EXPECT_EQ(o.name, "ROI 7");
    ASSERT_EQ(o.planes.size(), 1u);
    ASSERT_EQ(o.planes[0].contours.size(), 1u);
    EXPECT_EQ(o.planes[0].contours[0].points.size(), 4u);
    EXPECT_NEAR(std::abs(polygon_area(o.planes[0].contours[0].points)), 100.0, 1e-9);
    ASSERT_EQ(o.markers.size(), 1u);
    EXPECT_EQ(o.markers[0], (Vec3{1, 2, 3}));
    EXPECT_TRUE(has_warning(report, "ROI 7", "2 repeated and 2 collinear"));
    EXPECT_TRUE(has_warning(report, "ROI 7", "1 POINT"));
    EXPECT_TRUE(has_warning(report, "ROI 7", "no ROI name"));
}

TEST(PlanarContours, DegenerateSelfCrossingAndKeyholeContoursAreReported) {
    RawContourSet raw;
    raw.source = "synthetic";
    RawRoi roi;
    roi.number = 1;
    roi.name = "odd";
    RawContour line;  // zero area
    line.points = {{0, 0, 0}, {5, 0, 0}, {10, 0, 0}, {5, 0, 0}};
    roi.contours.push_back(line);
    RawContour bowtie;
    bowtie.points = {{0, 0, 3}, {10, 10, 3}, {10, 0, 3}, {0, 6, 3}};
    roi.contours.push_back(bowtie);
    // a square with a square hole joined by a keyhole cut along y = 5 from x = 0 to 3
    RawContour keyhole;
    keyhole.points = {{0, 0, 6}, {10, 0, 6}, {10, 10, 6}, {0, 10, 6}, {0, 5, 6}, {3, 5, 6},
                      {3, 7, 6}, {7, 7, 6},  {7, 3, 6},   {3, 3, 6},  {3, 5, 6}, {0, 5, 6}};
    roi.contours.push_back(keyhole);
    raw.rois.push_back(roi);
    RawRoi empty;
    empty.number = 2;
    empty.name = "nothing";
    raw.rois.push_back(empty);
    Report report;
    const PlanarContours out = clean_planar_contours(raw, {}, report);
    EXPECT_TRUE(has_warning(report, "ROI 1 (odd)", "1 contour(s) with fewer than 3"));
    EXPECT_TRUE(has_warning(report, "ROI 1 (odd)", "1 contour(s) cross themselves"));
    EXPECT_TRUE(has_warning(report, "ROI 1 (odd)", "1 contour(s) with keyhole cuts"));
    EXPECT_TRUE(has_warning(report, "ROI 2 (nothing)", "no contours"));
    ASSERT_EQ(out.objects[0].planes.size(), 2u);  // the line became markers
    EXPECT_EQ(out.objects[0].markers.size(), 4u);
    // the keyhole polygon keeps its area: 100 - 16
    EXPECT_NEAR(std::abs(polygon_area(out.objects[0].planes[1].contours[0].points)), 84.0, 1e-9);
}

TEST(PlanarContours, TiltedPlanesKeepTheirNormalAndSpacing) {
    // squares on planes tilted 12 degrees about x, 2.5 mm apart along the normal, one missing
    const double a = 12.0 * M_PI / 180.0;
    const Vec3 n{0, -std::sin(a), std::cos(a)};
    const Vec3 v{0, std::cos(a), std::sin(a)};
    RawContourSet raw;
    raw.source = "tilted";
    RawRoi roi;
    roi.number = 3;
    roi.name = "tilted";
    for (const int k : {0, 1, 2, 4, 5}) {
        RawContour c;
        for (const Vec2 q : {Vec2{0, 0}, Vec2{20, 0}, Vec2{20, 15}, Vec2{0, 15}}) {
            c.points.push_back(q.x * Vec3{1, 0, 0} + q.y * v + (2.5 * k + 1.0) * n);
        }
        roi.contours.push_back(c);
    }
    raw.rois.push_back(roi);
    Report report;
    const PlanarContours out = clean_planar_contours(raw, {}, report);
    EXPECT_LT(norm(out.normal - n), 1e-9);
    ASSERT_EQ(out.objects[0].planes.size(), 5u);
    const std::vector<double> expected{1.0, 3.5, 6.0, 11.0, 13.5};
    for (std::size_t i = 0; i < 5; ++i) {
        EXPECT_NEAR(out.objects[0].planes[i].w, expected[i], 1e-9);
        EXPECT_NEAR(std::abs(polygon_area(out.objects[0].planes[i].contours[0].points)), 300.0,
                    1e-9);
    }
    EXPECT_TRUE(has_warning(report, "tilted", "tilted 12 degrees"));
    EXPECT_TRUE(has_warning(report, "tilted", "uneven plane spacing"));
    EXPECT_TRUE(has_warning(report, "ROI 3 (tilted)", "about 1 plane(s) inside its range"));

    // a point 2 mm off its plane is refused
    raw.rois[0].contours[1].points[2] = raw.rois[0].contours[1].points[2] + 2.0 * n;
    try {
        clean_planar_contours(raw, {}, report);
        FAIL() << "expected an error";
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::InvalidInput);
        EXPECT_NE(std::string(e.what()).find("off the contour's plane"), std::string::npos);
    }
}

// ---- bad DICOM: each a copy of rtss.dcm with one defect -------------------------------------

fs::path broken_copy(const std::string& name, const std::function<void(DcmDataset&)>& edit) {
    DcmFileFormat file;
    EXPECT_TRUE(file.loadFile(kRtstruct.c_str()).good());
    edit(*file.getDataset());
    const fs::path out = test::fresh_temp_dir("planar_" + name) / "rtss.dcm";
    EXPECT_TRUE(file.saveFile(out.c_str(), EXS_LittleEndianExplicit).good());
    return out;
}

DcmItem& first_contour(DcmDataset& d) {
    DcmSequenceOfItems* rois = nullptr;
    d.findAndGetSequence(DCM_ROIContourSequence, rois);
    DcmSequenceOfItems* contours = nullptr;
    rois->getItem(0)->findAndGetSequence(DCM_ContourSequence, contours);
    return *contours->getItem(0);
}

std::string error_of(const fs::path& path, ErrorCode expected) {
    try {
        read_raw_contours(path.string(), "");
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), expected) << e.what();
        return e.what();
    }
    ADD_FAILURE() << path << ": no error";
    return {};
}

TEST(PlanarContours, BadDicomIsRefusedWithAClearMessage) {
    EXPECT_NE(error_of(kCt, ErrorCode::Unsupported).find("not an RTSTRUCT"), std::string::npos);

    const fs::path no_frame = broken_copy("no_frame", [](DcmDataset& d) {
        d.findAndDeleteElement(DCM_ReferencedFrameOfReferenceSequence);
    });
    EXPECT_NE(error_of(no_frame, ErrorCode::InvalidInput).find("does not declare"),
              std::string::npos);

    const fs::path not_number = broken_copy("not_number", [](DcmDataset& d) {
        first_contour(d).putAndInsertString(DCM_ContourData, "1.5\\abc\\2");
    });
    EXPECT_NE(error_of(not_number, ErrorCode::InvalidInput).find("'abc'"), std::string::npos);

    const fs::path odd = broken_copy("odd", [](DcmDataset& d) {
        first_contour(d).putAndInsertString(DCM_ContourData, "1\\2\\3\\4\\5\\6\\7");
    });
    EXPECT_NE(error_of(odd, ErrorCode::InvalidInput).find("7 values"), std::string::npos);

    const fs::path count = broken_copy("count", [](DcmDataset& d) {
        first_contour(d).putAndInsertString(DCM_NumberOfContourPoints, "999");
    });
    EXPECT_NE(error_of(count, ErrorCode::InvalidInput).find("Number of Contour Points is 999"),
              std::string::npos);

    const fs::path type = broken_copy("type", [](DcmDataset& d) {
        first_contour(d).putAndInsertString(DCM_ContourGeometricType, "CURVED");
    });
    EXPECT_NE(error_of(type, ErrorCode::InvalidInput).find("'CURVED'"), std::string::npos);

    // truncated: the first 3000 bytes of the file
    const fs::path truncated = test::fresh_temp_dir("planar_truncated") / "rtss.dcm";
    {
        const std::string bytes = test::read_file(kRtstruct);
        std::ofstream(truncated, std::ios::binary) << bytes.substr(0, 3000);
    }
    error_of(truncated, ErrorCode::InvalidInput);
}

TEST(PlanarContours, BadContourJsonIsRefusedWithItsPath) {
    const fs::path dir = test::fresh_temp_dir("planar_json");
    const auto write = [&](const std::string& name, const std::string& text) {
        std::ofstream(dir / name) << text;
        return dir / name;
    };
    const std::string head = R"({"format": "planar contours v1", "rois": [)";
    EXPECT_NE(
        error_of(write("a.json",
                       head + R"({"slices": [{"z": 1, "contours": [{"points": [[0, "x"]]}]}]}]})"),
                 ErrorCode::InvalidInput)
            .find("rois[0].slices[0].contours[0].points[0]"),
        std::string::npos);
    EXPECT_NE(
        error_of(write("b.json", head + R"({"color_rgb": [1, 2]}]})"), ErrorCode::InvalidInput)
            .find("color_rgb"),
        std::string::npos);
    EXPECT_NE(error_of(write("d.json", head + R"({"number": 1e20}]})"), ErrorCode::InvalidInput)
                  .find("rois[0].number"),
              std::string::npos);
    EXPECT_NE(
        error_of(write("c.json", head + "{]"), ErrorCode::InvalidInput).find("not valid JSON"),
        std::string::npos);
}

TEST(PlanarContours, CliAnswersBadDicomWithExitTwo) {
    // note: the output folder is a subfolder: a build refuses a folder that holds other files
    // (here the captured stderr)
    const fs::path out = test::fresh_temp_dir("planar_cli");
    const std::string command = "'" + test::cli_path().string() + "' build '" + kCt.string() +
                                "' -o '" + (out / "model").string() + "' --quiet 2>'" +
                                (out / "err").string() + "'";
    const int status = std::system(command.c_str());
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 2);
    const std::string err = test::read_file(out / "err");
    EXPECT_EQ(err.rfind("strata: error: ", 0), 0u) << err;
    EXPECT_NE(err.find("not an RTSTRUCT"), std::string::npos) << err;

    // a pitch far too fine for the structures' extent
    const std::string fine = "'" + test::cli_path().string() + "' build '" + kJson.string() +
                             "' --contour-pitch 1e-9 -o '" + (out / "model").string() +
                             "' --quiet 2>'" + (out / "err2").string() + "'";
    const int fine_status = std::system(fine.c_str());
    ASSERT_TRUE(WIFEXITED(fine_status));
    EXPECT_EQ(WEXITSTATUS(fine_status), 2) << test::read_file(out / "err2");
    EXPECT_NE(test::read_file(out / "err2").find("too fine"), std::string::npos);
}

}  // namespace
}  // namespace strata

namespace strata {
namespace {

TEST(PlanarContours, CliInfoListsEveryStructure) {
    const fs::path out = test::fresh_temp_dir("planar_info");
    const std::string command = "'" + test::cli_path().string() + "' info '" + kRtstruct.string() +
                                "' --json >'" + (out / "info.json").string() + "' 2>'" +
                                (out / "err").string() + "'";
    const int status = std::system(command.c_str());
    ASSERT_TRUE(WIFEXITED(status));
    ASSERT_EQ(WEXITSTATUS(status), 0) << test::read_file(out / "err");
    const nlohmann::json info = nlohmann::json::parse(test::read_file(out / "info.json"));
    // against the JSON export of the same structure set, read here without strata
    const nlohmann::json json = nlohmann::json::parse(test::read_file(kJson));
    ASSERT_EQ(info["structures"].size(), json["rois"].size());
    for (std::size_t i = 0; i < json["rois"].size(); ++i) {
        const nlohmann::json& roi = json["rois"][i];
        const nlohmann::json& s = info["structures"][i];
        EXPECT_EQ(s["number"], roi["number"]);
        EXPECT_EQ(s["name"], roi["name"]);
        EXPECT_EQ(s["color_srgb"], roi["color_rgb"]);
        std::size_t contours = 0;
        for (const nlohmann::json& slice : roi["slices"]) {
            contours += slice["contours"].size();
        }
        EXPECT_EQ(s["contours"].get<std::size_t>(), contours) << roi["name"];
        EXPECT_EQ(s["planes"].get<std::size_t>(), roi["slices"].size()) << roi["name"];
    }
    EXPECT_EQ(info["reference_grid"]["columns"], 512);
}

}  // namespace
}  // namespace strata
