#include "mesh/mesh_io.h"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "core/error.h"
#include "mesh/mesh_checks.h"
#include "support/mesh_shapes.h"
#include "support/test_paths.h"

namespace strata {
namespace {

namespace fs = std::filesystem;

std::string read_bytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const fs::path& path, const std::string& bytes) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// note: one coordinate per call: GCC 12.2 at -O2 drops the float rounding when the SLP
// vectorizer pairs two double -> float -> double conversions into adjacent fields
// (`Vec3{float(p.x), float(p.y), ...}` returns p.x and p.y unrounded).
[[gnu::noinline]] double rounded_to_float(double x) {
    return static_cast<float>(x);
}

Vec3 rounded_to_float(Vec3 p) {
    return {rounded_to_float(p.x), rounded_to_float(p.y), rounded_to_float(p.z)};
}

/// A mesh whose coordinates are not floats (cos/sin values), with labels.
TriMesh sample_mesh() {
    TriMesh mesh = test::torus(7, 5, 2.0, 0.7);
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        mesh.labels.push_back(static_cast<std::uint16_t>(t * 977 % 65536));
    }
    return mesh;
}

/// Expects `read(path)` to throw Error{code} whose message holds the file name and `fragment`.
void expect_read_error(const fs::path& path, ErrorCode code, const std::string& fragment) {
    try {
        read_mesh(path);
        ADD_FAILURE() << "no error reading " << path;
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), code) << e.what();
        EXPECT_NE(std::string(e.what()).find(path.filename().string()), std::string::npos)
            << e.what();
        EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos)
            << "message: " << e.what() << "\nexpected fragment: " << fragment;
    }
}

void expect_read_error(const fs::path& dir,
                       const std::string& name,
                       const std::string& bytes,
                       const std::string& fragment,
                       ErrorCode code = ErrorCode::InvalidInput) {
    write_bytes(dir / name, bytes);
    expect_read_error(dir / name, code, fragment);
}

std::string le32(std::uint32_t v) {
    std::string s(4, '\0');
    for (int i = 0; i < 4; ++i) {
        s[i] = static_cast<char>((v >> (8 * i)) & 0xFF);
    }
    return s;
}

std::string lef32(float f) {
    std::uint32_t bits = 0;
    std::memcpy(&bits, &f, 4);
    return le32(bits);
}

class MeshIo : public ::testing::Test {
protected:
    fs::path dir_ = test::fresh_temp_dir(
        std::string("mesh_io_") + ::testing::UnitTest::GetInstance()->current_test_info()->name());
};

// ---------------------------------------------------------------------------------------------
// Round trips

TEST_F(MeshIo, PlyRoundTripIsExactAtFloatPrecisionAndKeepsLabels) {
    TriMesh mesh = sample_mesh();
    mesh.positions.push_back({0.1, 0.2, 0.3});  // unreferenced: PLY keeps it
    write_mesh(mesh, dir_ / "m.ply");
    const TriMesh back = read_mesh(dir_ / "m.ply");
    ASSERT_EQ(back.positions.size(), mesh.positions.size());
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
        EXPECT_EQ(back.positions[v], rounded_to_float(mesh.positions[v])) << "vertex " << v;
    }
    EXPECT_EQ(back.triangles, mesh.triangles);
    EXPECT_EQ(back.labels, mesh.labels);
    EXPECT_EQ(read_bytes(dir_ / "m.ply").substr(0, 36), "ply\nformat binary_little_endian 1.0\n");
}

TEST_F(MeshIo, ObjRoundTripIsExactAtFloatPrecision) {
    const TriMesh mesh = sample_mesh();
    write_mesh(mesh, dir_ / "m.obj");
    const TriMesh back = read_mesh(dir_ / "m.obj");
    ASSERT_EQ(back.positions.size(), mesh.positions.size());
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
        EXPECT_EQ(rounded_to_float(back.positions[v]), rounded_to_float(mesh.positions[v]))
            << "vertex " << v;
    }
    EXPECT_EQ(back.triangles, mesh.triangles);
    EXPECT_TRUE(back.labels.empty());
}

/// Unit normals, one per vertex of `mesh`, not floats (sin/cos values).
std::vector<Vec3> sample_normals(const TriMesh& mesh) {
    std::vector<Vec3> normals;
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
        const double a = 0.37 * double(v);
        normals.push_back({std::cos(a) * 0.6, std::sin(a) * 0.6, 0.8});
    }
    return normals;
}

TEST_F(MeshIo, PlyWritesNormalsAsVertexPropertiesAfterThePositions) {
    const TriMesh mesh = sample_mesh();
    const std::vector<Vec3> normals = sample_normals(mesh);
    write_mesh(mesh, dir_ / "n.ply", normals);
    const std::string bytes = read_bytes(dir_ / "n.ply");
    const std::string header_end = "end_header\n";
    const std::size_t body = bytes.find(header_end) + header_end.size();
    const std::string header = bytes.substr(0, body);
    EXPECT_NE(header.find("property float z\nproperty float nx\nproperty float ny\n"
                          "property float nz\nelement face"),
              std::string::npos)
        << header;
    for (std::size_t v = 0; v < normals.size(); ++v) {
        for (int k = 0; k < 3; ++k) {
            const float expected = static_cast<float>(normals[v][k]);
            EXPECT_EQ(bytes.substr(body + 24 * v + 12 + 4 * std::size_t(k), 4), lef32(expected))
                << "vertex " << v << " component " << k;
        }
    }
    const TriMesh back = read_mesh(dir_ / "n.ply");  // readers skip the extra properties
    ASSERT_EQ(back.positions.size(), mesh.positions.size());
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
        EXPECT_EQ(back.positions[v], rounded_to_float(mesh.positions[v])) << "vertex " << v;
    }
    EXPECT_EQ(back.triangles, mesh.triangles);
    EXPECT_EQ(back.labels, mesh.labels);
}

TEST_F(MeshIo, ObjWritesNormalsAsVnReferencedByEveryCorner) {
    const TriMesh mesh = sample_mesh();
    const std::vector<Vec3> normals = sample_normals(mesh);
    write_mesh(mesh, dir_ / "n.obj", normals);
    std::ifstream in(dir_ / "n.obj");
    std::string line;
    std::size_t vn = 0;
    std::size_t faces = 0;
    while (std::getline(in, line)) {
        if (line.rfind("vn ", 0) == 0) {
            std::istringstream fields(line.substr(3));
            double x = 0, y = 0, z = 0;
            fields >> x >> y >> z;
            ASSERT_LT(vn, normals.size());
            EXPECT_EQ(float(x), float(normals[vn].x));
            EXPECT_EQ(float(y), float(normals[vn].y));
            EXPECT_EQ(float(z), float(normals[vn].z));
            ++vn;
        } else if (line.rfind("f ", 0) == 0) {
            const auto& t = mesh.triangles[faces++];
            std::string expected = "f";
            for (const std::uint32_t v : t) {
                expected += " " + std::to_string(v + 1) + "//" + std::to_string(v + 1);
            }
            EXPECT_EQ(line, expected);
        }
    }
    EXPECT_EQ(vn, normals.size());
    EXPECT_EQ(faces, mesh.triangles.size());
    EXPECT_EQ(read_mesh(dir_ / "n.obj").triangles, mesh.triangles);
}

TEST_F(MeshIo, WriterRejectsNormalsOfTheWrongCountOrLength) {
    const TriMesh mesh = sample_mesh();
    std::vector<Vec3> normals = sample_normals(mesh);
    normals.pop_back();
    EXPECT_THROW(write_mesh(mesh, dir_ / "bad.ply", normals), Error);
    normals = sample_normals(mesh);
    normals[3] = {2.0, 0.0, 0.0};
    EXPECT_THROW(write_mesh(mesh, dir_ / "bad.obj", normals), Error);
    EXPECT_FALSE(fs::exists(dir_ / "bad.ply"));
    EXPECT_FALSE(fs::exists(dir_ / "bad.obj"));
}

TEST_F(MeshIo, StlRoundTripKeepsCornersAndWeldsVertices) {
    const TriMesh mesh = sample_mesh();  // all vertices used and distinct
    write_mesh(mesh, dir_ / "m.stl");
    const TriMesh back = read_mesh(dir_ / "m.stl");
    ASSERT_EQ(back.triangles.size(), mesh.triangles.size());
    EXPECT_EQ(back.positions.size(), mesh.positions.size());  // welded back to shared vertices
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        for (int k = 0; k < 3; ++k) {
            EXPECT_EQ(back.positions[back.triangles[t][k]],
                      rounded_to_float(mesh.positions[mesh.triangles[t][k]]))
                << "triangle " << t << " corner " << k;
        }
    }
    EXPECT_TRUE(is_closed_manifold(check_mesh(back)));
    EXPECT_NE(read_bytes(dir_ / "m.stl").substr(0, 5), "solid");
}

TEST_F(MeshIo, StlRoundTripKeepsIndicesWhenVerticesAreInFirstUseOrder) {
    const TriMesh mesh = test::weld_exact(test::cube());  // numbered by first use
    write_mesh(mesh, dir_ / "cube.stl");
    const TriMesh back = read_mesh(dir_ / "cube.stl");
    EXPECT_EQ(back.positions, mesh.positions);
    EXPECT_EQ(back.triangles, mesh.triangles);
}

TEST_F(MeshIo, EmptyMeshRoundTripsInEveryFormat) {
    for (const char* name : {"e.ply", "e.obj", "e.stl"}) {
        write_mesh(TriMesh{}, dir_ / name);
        const TriMesh back = read_mesh(dir_ / name);
        EXPECT_TRUE(back.positions.empty()) << name;
        EXPECT_TRUE(back.triangles.empty()) << name;
    }
}

TEST_F(MeshIo, ExtensionIsCaseInsensitive) {
    write_mesh(test::cube(), dir_ / "CUBE.PLY");
    EXPECT_EQ(read_mesh(dir_ / "CUBE.PLY").triangles, test::cube().triangles);
}

TEST_F(MeshIo, UnknownExtensionIsUnsupported) {
    try {
        write_mesh(test::cube(), dir_ / "cube.off");
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::Unsupported);
        EXPECT_NE(std::string(e.what()).find("expected .ply, .obj or .stl"), std::string::npos);
    }
    write_bytes(dir_ / "cube.off", "OFF\n");
    expect_read_error(dir_ / "cube.off", ErrorCode::Unsupported, "expected .ply, .obj or .stl");
}

// ---------------------------------------------------------------------------------------------
// Writing failures

TEST_F(MeshIo, WriteIntoFileParentFailsWithIoError) {
    write_bytes(dir_ / "not_a_folder", "keep me");
    try {
        write_mesh(test::cube(), dir_ / "not_a_folder" / "cube.ply");
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::Io) << e.what();
    }
    EXPECT_EQ(read_bytes(dir_ / "not_a_folder"), "keep me");
}

TEST_F(MeshIo, FailedWriteLeavesOldFileIntact) {
    write_mesh(test::cube(), dir_ / "cube.ply");
    const std::string old = read_bytes(dir_ / "cube.ply");

    TriMesh broken = test::cube();
    broken.triangles.push_back({0, 1, 8});
    try {
        write_mesh(broken, dir_ / "cube.ply");
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::InvalidInput);
        EXPECT_NE(
            std::string(e.what()).find("triangle 12: vertex index 8 out of range, expected < 8"),
            std::string::npos)
            << e.what();
    }
    EXPECT_EQ(read_bytes(dir_ / "cube.ply"), old);
    EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1);
}

TEST_F(MeshIo, FailedRenameLeavesNoTemporaryFile) {
    fs::create_directories(dir_ / "taken.obj" / "inside");  // a non-empty folder in the way
    try {
        write_mesh(test::cube(), dir_ / "taken.obj");
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::Io) << e.what();
    }
    EXPECT_TRUE(fs::is_directory(dir_ / "taken.obj" / "inside"));
    EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1);
}

TEST_F(MeshIo, WriterRejectsBadMeshes) {
    TriMesh labels = test::cube();
    labels.labels = {1, 2, 3};
    EXPECT_THROW(write_mesh(labels, dir_ / "a.ply"), Error);
    TriMesh huge = test::cube();
    huge.positions[3].x = 1e300;  // beyond float32
    try {
        write_mesh(huge, dir_ / "a.stl");
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::InvalidInput);
        EXPECT_NE(std::string(e.what()).find("vertex 3"), std::string::npos) << e.what();
    }
    EXPECT_FALSE(fs::exists(dir_ / "a.ply"));
    EXPECT_FALSE(fs::exists(dir_ / "a.stl"));
}

TEST_F(MeshIo, MissingFileIsIoError) {
    expect_read_error(dir_ / "missing.ply", ErrorCode::Io, "cannot open");
}

// ---------------------------------------------------------------------------------------------
// PLY reading

TEST_F(MeshIo, ReadsAsciiPlyWithExtraPropertiesQuadsAndLabels) {
    const std::string ply =
        "ply\r\n"
        "format ascii 1.0\r\n"
        "comment made by hand\r\n"
        "element vertex 4\r\n"
        "property double x\r\nproperty double y\r\nproperty double z\r\n"
        "property uchar red\r\n"
        "element face 1\r\n"
        "property list uchar int vertex_index\r\n"
        "property int label\r\n"
        "element edge 1\r\n"
        "property int vertex1\r\nproperty int vertex2\r\n"
        "end_header\r\n"
        "0 0 0 255\r\n1 0 0 0\r\n1 1 0.5 0\r\n0 1 1e-3 7\r\n"
        "\r\n"
        "4 0 1 2 3 42\r\n"
        "0 2\r\n";
    write_bytes(dir_ / "quad.ply", ply);
    const TriMesh mesh = read_mesh(dir_ / "quad.ply");
    EXPECT_EQ(mesh.positions, (std::vector<Vec3>{{0, 0, 0}, {1, 0, 0}, {1, 1, 0.5}, {0, 1, 1e-3}}));
    EXPECT_EQ(mesh.triangles, (std::vector<test::Triangle>{{0, 1, 2}, {0, 2, 3}}));
    EXPECT_EQ(mesh.labels, (std::vector<std::uint16_t>{42, 42}));
}

TEST_F(MeshIo, ReadsBinaryPlyWithSkippedListsAndOtherTypes) {
    std::string ply =
        "ply\nformat binary_little_endian 1.0\n"
        "element vertex 3\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property list uchar float extra\n"
        "element face 1\n"
        "property uchar flags\n"
        "property list uchar uint vertex_indices\n"
        "end_header\n";
    for (int v = 0; v < 3; ++v) {
        ply += lef32(v == 1 ? 2.5f : 0.0f) + lef32(v == 2 ? -1.25f : 0.0f) + lef32(0.5f);
        ply += std::string(1, char(v));  // v extra floats
        for (int i = 0; i < v; ++i) {
            ply += lef32(9.0f);
        }
    }
    ply += std::string(1, '\x07') + std::string(1, '\x03') + le32(0) + le32(1) + le32(2);
    write_bytes(dir_ / "b.ply", ply);
    const TriMesh mesh = read_mesh(dir_ / "b.ply");
    EXPECT_EQ(mesh.positions, (std::vector<Vec3>{{0, 0, 0.5}, {2.5, 0, 0.5}, {0, -1.25, 0.5}}));
    EXPECT_EQ(mesh.triangles, (std::vector<test::Triangle>{{0, 1, 2}}));
    EXPECT_TRUE(mesh.labels.empty());
}

TEST_F(MeshIo, PlyBadHeaderIsRejected) {
    expect_read_error(dir_, "a.ply", "PLY\nformat ascii 1.0\nend_header\n",
                      "not a PLY file: first line is 'PLY', expected 'ply'");
    expect_read_error(dir_, "b.ply", "ply\nformat ascii 1.0\nelement vertex 0\n",
                      "PLY header has no end_header line");
    expect_read_error(dir_, "c.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty half x\n",
                      "PLY header line 4: unknown property type 'half'");
    expect_read_error(dir_, "d.ply", "ply\nformat ascii 1.0\nelement face 0\nend_header\n",
                      "no 'vertex' element");
    expect_read_error(dir_, "e.ply", "ply\nformat binary_big_endian 1.0\nend_header\n",
                      "binary_big_endian is not supported", ErrorCode::Unsupported);
    expect_read_error(dir_, "f.ply",
                      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n0\n",
                      "needs scalar properties x, y and z");
}

TEST_F(MeshIo, TruncatedPlyIsRejected) {
    write_mesh(test::cube(), dir_ / "full.ply");
    const std::string full = read_bytes(dir_ / "full.ply");
    // Cut inside the face element: the vertices fit, face 11 does not.
    expect_read_error(dir_, "cut.ply", full.substr(0, full.size() - 5),
                      "truncated: face 11 of 12 (byte");
    // Cut inside the vertices: caught before reading them.
    const std::size_t header = full.find("end_header\n") + 11;
    expect_read_error(dir_, "cut2.ply", full.substr(0, header + 50),
                      "truncated: element 'vertex' has 8 rows of 12 bytes, but only 50 bytes");
}

TEST_F(MeshIo, PlyHeaderCountLargerThanFileIsRejectedWithoutAllocating) {
    expect_read_error(dir_, "huge.ply",
                      "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\n"
                      "property float x\nproperty float y\nproperty float z\nend_header\n",
                      "truncated: element 'vertex' has 4000000000 rows");
    expect_read_error(dir_, "huge_ascii.ply",
                      "ply\nformat ascii 1.0\nelement vertex 4000000000\n"
                      "property float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n",
                      "truncated: vertex 1 of 4000000000 (line 8): unexpected end of file");
}

TEST_F(MeshIo, PlyVertexIndexOutOfRangeIsRejected) {
    TriMesh mesh = test::cube();
    write_mesh(mesh, dir_ / "full.ply");
    std::string bytes = read_bytes(dir_ / "full.ply");
    // Face 5 starts after the header, 8 vertices and 5 faces of 13 bytes; its second index:
    const std::size_t at = bytes.find("end_header\n") + 11 + 8 * 12 + 5 * 13 + 1 + 4;
    bytes.replace(at, 4, le32(9));
    expect_read_error(dir_, "bad.ply", bytes,
                      "face 5 of 12 (byte " + std::to_string(at + 4) +
                          "): vertex index 9 out of range, expected 0 to 7 (8 vertices)");

    expect_read_error(dir_, "neg.ply",
                      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float "
                      "y\nproperty float z\nelement face 1\nproperty list uchar int "
                      "vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n",
                      "face 0 of 1 (line 13): vertex index -1 out of range");
}

TEST_F(MeshIo, PlyFaceWithTwoCornersIsRejected) {
    expect_read_error(dir_, "two.ply",
                      "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float "
                      "y\nproperty float z\nelement face 1\nproperty list uchar int "
                      "vertex_indices\nend_header\n0 0 0\n1 0 0\n2 0 1\n",
                      "face 0 of 1 (line 12): 2 corners, expected at least 3");
}

TEST_F(MeshIo, PlyTrailingBytesAreRejected) {
    write_mesh(test::cube(), dir_ / "full.ply");
    expect_read_error(dir_, "long.ply", read_bytes(dir_ / "full.ply") + "xyz",
                      "3 unexpected bytes after the last element");
    expect_read_error(dir_, "long.ply",
                      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float "
                      "y\nproperty float z\nend_header\n0 0 0\n1 1 1\n",
                      "unexpected data after the last element at line 9");
}

TEST_F(MeshIo, AsciiPlyValueErrorsAreRejected) {
    const std::string head =
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty "
        "float z\nend_header\n";
    expect_read_error(dir_, "few.ply", head + "0 0\n",
                      "vertex 0 of 1 (line 8): line 8 has too few");
    expect_read_error(dir_, "many.ply", head + "0 0 0 0\n", "line 8 has 4 values, expected 3");
    expect_read_error(dir_, "nan.ply", head + "0 abc 0\n", "'abc' is not a number");
    expect_read_error(dir_, "inf.ply", head + "0 inf 0\n", "non-finite coordinate y");
}

// ---------------------------------------------------------------------------------------------
// OBJ reading

TEST_F(MeshIo, ReadsObjCornerFormsNegativeIndicesAndPolygons) {
    const std::string obj =
        "# comment\n"
        "mtllib x.mtl\n"
        "o thing\n"
        "v 0 0 0\nv 1 0 0 # trailing comment\nv 1 1 0 1.0\nv 0 1 0 0.5 0.5 0.5\n"
        "vt 0 0\nvn 0 0 1\n"
        "g part\nusemtl m\ns off\n"
        "f 1/1 2/1 3/1\n"
        "f 1//1 3//1 4//1\n"
        "f -4/1/1 -3/1/1 -2/1/1 -1/1/1\n"
        "f 1 2 \\\n 4\n";
    write_bytes(dir_ / "forms.obj", obj);
    const TriMesh mesh = read_mesh(dir_ / "forms.obj");
    EXPECT_EQ(mesh.positions.size(), 4u);
    EXPECT_EQ(mesh.triangles,
              (std::vector<test::Triangle>{{0, 1, 2}, {0, 2, 3}, {0, 1, 2}, {0, 2, 3}, {0, 1, 3}}));
}

TEST_F(MeshIo, ObjFaceIndexZeroIsRejected) {
    expect_read_error(dir_, "zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
                      "line 4: face vertex index 0 is invalid, OBJ indices start at 1");
}

TEST_F(MeshIo, ObjFaceIndexBeyondCountIsRejected) {
    expect_read_error(dir_, "beyond.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n",
                      "line 5: face vertex index 4 out of range, the file has 3 vertices");
    expect_read_error(dir_, "before.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n",
                      "line 4: relative face vertex index -4 points before the first vertex, "
                      "only 3 vertices so far");
}

TEST_F(MeshIo, ObjFacesMayReferToLaterVertices) {
    write_bytes(dir_ / "late.obj", "f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n");
    const TriMesh mesh = read_mesh(dir_ / "late.obj");
    EXPECT_EQ(mesh.triangles, (std::vector<test::Triangle>{{0, 1, 2}}));
}

TEST_F(MeshIo, ObjSyntaxErrorsAreRejected) {
    expect_read_error(dir_, "short.obj", "v 0 0\n", "line 1: 'v' needs 3 coordinates");
    expect_read_error(dir_, "word.obj", "v 0 zero 0\n", "vertex coordinate 'zero' is not a number");
    expect_read_error(dir_, "nan.obj", "v 0 nan 0\n", "vertex 1 has a non-finite coordinate");
    expect_read_error(dir_, "two.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n",
                      "line 3: face with 2 corners, expected at least 3");
    expect_read_error(dir_, "corner.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/x 2 3\n",
                      "face corner '1/x'");
    expect_read_error(dir_, "stmt.obj", "v 0 0 0\nbogus 1 2\n",
                      "line 2: unknown statement 'bogus'");
    expect_read_error(dir_, "binary.obj",
                      std::string("\x7f"
                                  "ELF\x02\x01",
                                  6),
                      "line 1: unknown statement");
}

// ---------------------------------------------------------------------------------------------
// STL reading

TEST_F(MeshIo, StlSizeMismatchIsRejected) {
    write_mesh(test::cube(), dir_ / "full.stl");
    const std::string full = read_bytes(dir_ / "full.stl");
    expect_read_error(dir_, "short.stl", full.substr(0, full.size() - 1),
                      "size mismatch: the header says 12 triangles, which take 84 + 50 * 12 = "
                      "684 bytes, but the file has 683 bytes");
    expect_read_error(dir_, "tiny.stl", full.substr(0, 40), "truncated: 40 bytes");
}

TEST_F(MeshIo, BinaryStlWhoseHeaderSaysSolidIsReadAsBinary) {
    write_mesh(test::cube(), dir_ / "full.stl");
    std::string bytes = read_bytes(dir_ / "full.stl");
    bytes.replace(0, 10, "solid cube");
    write_bytes(dir_ / "solid.stl", bytes);
    EXPECT_EQ(read_mesh(dir_ / "solid.stl").triangles.size(), 12u);
    // With a wrong size it is still recognised as binary (it holds NUL bytes).
    expect_read_error(dir_, "solid_short.stl", bytes.substr(0, 600), "size mismatch");
}

TEST_F(MeshIo, StlNonFiniteCoordinateIsRejected) {
    std::string bytes(80, ' ');
    bytes += le32(1) + std::string(12, '\0');
    for (int i = 0; i < 9; ++i) {
        bytes += lef32(i == 4 ? std::numeric_limits<float>::quiet_NaN() : 1.0f * i);
    }
    bytes += std::string(2, '\0');
    expect_read_error(dir_, "nan.stl", bytes,
                      "triangle 0 of 1: corner 1 has a non-finite coordinate");
}

TEST_F(MeshIo, ReadsAsciiStlAndWeldsEqualCorners) {
    const std::string stl =
        "solid two\n"
        "  facet normal 0 0 1\n    outer loop\n"
        "      vertex 0 0 0\n      vertex 1 0 0\n      vertex 1 1 0\n"
        "    endloop\n  endfacet\n"
        "  facet normal 0 0 1\n    outer loop\n"
        "      vertex 0 0 0\n      vertex 1 1 0\n      vertex 0 1 -0.0\n"
        "    endloop\n  endfacet\n"
        "endsolid two\n";
    write_bytes(dir_ / "two.stl", stl);
    const TriMesh mesh = read_mesh(dir_ / "two.stl");
    EXPECT_EQ(mesh.positions, (std::vector<Vec3>{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}));
    EXPECT_EQ(mesh.triangles, (std::vector<test::Triangle>{{0, 1, 2}, {0, 2, 3}}));
}

TEST_F(MeshIo, AsciiStlErrorsAreRejected) {
    const std::string facet_start = "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n";
    expect_read_error(dir_, "cut.stl", facet_start + "vertex 1 0 0\n",
                      "truncated: ASCII STL ends after line 5, expected 'vertex <x> <y> <z>'");
    expect_read_error(dir_, "word.stl", facet_start + "vertex 1 0\n",
                      "ASCII STL line 5: found 'vertex 1 0', expected 'vertex <x> <y> <z>'");
    expect_read_error(dir_, "loop.stl", "solid x\nfacet normal 0 0 1\nouter loops\n",
                      "ASCII STL line 3: found 'outer loops', expected 'outer loop'");
    expect_read_error(dir_, "end.stl", "solid x\n", "expected 'facet' or 'endsolid'");
}

}  // namespace
}  // namespace strata
