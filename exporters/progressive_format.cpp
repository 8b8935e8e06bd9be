#include "exporters/progressive_format.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "core/error.h"

namespace strata::format {

namespace {

void put(std::string& out, std::uint32_t v, int bytes) {
    for (int i = 0; i < bytes; ++i) {
        out.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
    }
}

std::uint32_t get(std::string_view bytes, std::size_t at, int size) {
    std::uint32_t v = 0;
    for (int i = size - 1; i >= 0; --i) {
        v = (v << 8) | static_cast<unsigned char>(bytes[at + static_cast<std::size_t>(i)]);
    }
    return v;
}

[[noreturn]] void fail(const std::string& where, std::size_t at, const std::string& what) {
    throw Error(ErrorCode::InvalidInput,
                where + ": byte " + std::to_string(at) + " of the DAG table: " + what);
}

}  // namespace

std::string encode_dag_table(const DagTable& table) {
    const int id_bytes = table.clusters <= 65535 ? 2 : 4;
    std::string out(kDagMagic.begin(), kDagMagic.end());
    put(out, table.clusters, 4);
    put(out, static_cast<std::uint32_t>(table.groups.size()), 4);
    put(out, static_cast<std::uint32_t>(id_bytes), 4);
    for (const DagGroup& g : table.groups) {
        if (g.consumed.size() > 65535 || g.produced.size() > 65535) {
            throw Error(ErrorCode::InvalidInput, "a group lists more than 65535 clusters");
        }
        for (const float v : g.sphere) {
            std::uint32_t bits = 0;
            std::memcpy(&bits, &v, 4);
            put(out, bits, 4);
        }
        put(out, g.chunk_offset, 4);
        put(out, g.chunk_length, 4);
        put(out, static_cast<std::uint32_t>(g.consumed.size()), 2);
        put(out, static_cast<std::uint32_t>(g.produced.size()), 2);
        put(out, g.level, 2);
        put(out, g.fine, 2);
    }
    for (const DagGroup& g : table.groups) {
        for (const auto* list : {&g.consumed, &g.produced}) {
            for (const std::uint32_t c : *list) {
                if (c >= table.clusters) {
                    throw Error(ErrorCode::InvalidInput, "a group lists cluster " +
                                                             std::to_string(c) + " of " +
                                                             std::to_string(table.clusters));
                }
                put(out, c, id_bytes);
            }
        }
    }
    out.resize((out.size() + 3) / 4 * 4, '\0');
    return out;
}

std::size_t dag_table_length(std::string_view bytes, const std::string& where) {
    if (bytes.size() < kDagHeaderBytes) {
        fail(where, 0,
             std::to_string(bytes.size()) + " bytes left in the view, expected a 16-byte header");
    }
    if (bytes.substr(0, 4) != std::string_view(kDagMagic.data(), 4)) {
        fail(where, 0, "no \"SDAG\" magic");
    }
    const std::uint32_t groups = get(bytes, 8, 4);
    const std::uint32_t id_bytes = get(bytes, 12, 4);
    if (id_bytes != 2 && id_bytes != 4) {
        fail(where, 12, "idBytes " + std::to_string(id_bytes) + ", expected 2 or 4");
    }
    const std::uint64_t records = kDagHeaderBytes + std::uint64_t{kGroupRecordBytes} * groups;
    if (records > bytes.size()) {
        fail(where, 8,
             std::to_string(groups) + " group records do not fit the view's " +
                 std::to_string(bytes.size()) + " bytes left");
    }
    std::uint64_t ids = 0;
    for (std::uint32_t g = 0; g < groups; ++g) {
        const std::size_t at = kDagHeaderBytes + kGroupRecordBytes * g;
        ids += get(bytes, at + 24, 2) + get(bytes, at + 26, 2);
    }
    const std::uint64_t length = (records + ids * id_bytes + 3) / 4 * 4;
    if (length > bytes.size()) {
        fail(where, 0,
             "the table's counts need " + std::to_string(length) + " bytes, the view has " +
                 std::to_string(bytes.size()) + " left");
    }
    return static_cast<std::size_t>(length);
}

DagTable parse_dag_table(std::string_view bytes,
                         std::size_t group_count,
                         const std::string& where) {
    // magic, idBytes, the records within the bytes
    const std::size_t length = dag_table_length(bytes, where);
    if (length != bytes.size()) {
        fail(where, 0,
             "the table has " + std::to_string(bytes.size()) + " bytes, its counts need " +
                 std::to_string(length));
    }
    DagTable table;
    table.clusters = get(bytes, 4, 4);
    const std::uint32_t groups = get(bytes, 8, 4);
    const std::uint32_t id_bytes = get(bytes, 12, 4);
    if (table.clusters == 0) {
        fail(where, 4, "clusterCount 0, expected >= 1");
    }
    if (groups != group_count) {
        fail(where, 8,
             "groupCount " + std::to_string(groups) +
                 ", expected errors.length = " + std::to_string(group_count));
    }
    if (id_bytes == 2 && table.clusters > 65536) {
        fail(where, 12, "idBytes 2 cannot name " + std::to_string(table.clusters) + " clusters");
    }
    const std::uint64_t records = kDagHeaderBytes + std::uint64_t{kGroupRecordBytes} * groups;
    table.groups.resize(groups);
    for (std::uint32_t g = 0; g < groups; ++g) {
        const std::size_t at = kDagHeaderBytes + kGroupRecordBytes * g;
        DagGroup& out = table.groups[g];
        for (int k = 0; k < 4; ++k) {
            const std::uint32_t bits = get(bytes, at + 4 * static_cast<std::size_t>(k), 4);
            std::memcpy(&out.sphere[static_cast<std::size_t>(k)], &bits, 4);
            if (!std::isfinite(out.sphere[static_cast<std::size_t>(k)])) {
                fail(where, at + 4 * static_cast<std::size_t>(k),
                     "group " + std::to_string(g) + ": sphere value not finite");
            }
        }
        if (out.sphere[3] < 0.0f) {
            fail(where, at + 12, "group " + std::to_string(g) + ": negative radius");
        }
        out.chunk_offset = get(bytes, at + 16, 4);
        out.chunk_length = get(bytes, at + 20, 4);
        if (out.chunk_length == 0) {
            fail(where, at + 20,
                 "group " + std::to_string(g) + ": empty chunk, expected >= 1 byte");
        }
        const std::uint32_t consumed = get(bytes, at + 24, 2);
        const std::uint32_t produced = get(bytes, at + 26, 2);
        out.level = static_cast<std::uint16_t>(get(bytes, at + 28, 2));
        if (consumed == 0 || produced == 0) {
            fail(where, at + 24,
                 "group " + std::to_string(g) + ": consumes " + std::to_string(consumed) +
                     " and produces " + std::to_string(produced) + " clusters, expected >= 1 each");
        }
        if (out.level == 0) {
            fail(where, at + 28, "group " + std::to_string(g) + ": level 0, expected >= 1");
        }
        out.fine = static_cast<std::uint16_t>(get(bytes, at + 30, 2));
        out.consumed.resize(consumed);
        out.produced.resize(produced);
    }
    std::size_t at = static_cast<std::size_t>(records);
    for (std::uint32_t g = 0; g < groups; ++g) {
        for (auto* list : {&table.groups[g].consumed, &table.groups[g].produced}) {
            for (std::uint32_t& c : *list) {
                c = get(bytes, at, static_cast<int>(id_bytes));
                if (c >= table.clusters) {
                    fail(where, at,
                         "group " + std::to_string(g) + " lists cluster " + std::to_string(c) +
                             ", expected < clusterCount " + std::to_string(table.clusters));
                }
                at += id_bytes;
            }
        }
    }
    for (; at < bytes.size(); ++at) {
        if (bytes[at] != '\0') {
            fail(where, at, "padding not 0");
        }
    }
    return table;
}

std::uint16_t encode_fine(double bound, double error) {
    if (!(bound < error) || !(error > 0.0)) {
        return 0xffff;
    }
    if (!(bound > 0.0)) {
        return 0;
    }
    auto q = static_cast<std::uint32_t>(std::ceil(bound / error * kFineDenominator));
    q = std::min<std::uint32_t>(q, 0xffff);
    while (q < 0xffff && fine_error(error, static_cast<std::uint16_t>(q)) < bound) {
        ++q;
    }
    while (q > 0 && fine_error(error, static_cast<std::uint16_t>(q - 1)) >= bound) {
        --q;
    }
    return static_cast<std::uint16_t>(q);
}

double round_up_decimal(double x, int digits) {
    if (!std::isfinite(x) || x <= 0.0) {
        return x;
    }
    char text[64];
    std::snprintf(text, sizeof text, "%.*e", digits - 1, x);
    double r = std::strtod(text, nullptr);
    if (r >= x) {
        return r;
    }
    // next decimal up: the mantissa's last digit plus one
    char* e = std::strchr(text, 'e');
    const int exponent = std::atoi(e + 1);
    *e = '\0';
    std::string mantissa;
    for (const char* p = text; *p != '\0'; ++p) {
        if (*p != '.') {
            mantissa += *p;
        }
    }
    const long long m = std::atoll(mantissa.c_str()) + 1;
    std::snprintf(text, sizeof text, "%llde%d", m, exponent - (digits - 1));
    return std::strtod(text, nullptr);
}

}  // namespace strata::format
