#pragma once

// Text helpers shared by the header and colour-table parsers; internal to strata_input.

#include <charconv>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

namespace strata::detail {

/// `text` without leading and trailing white space (space, \t, \r, \n, \f, \v).
inline std::string_view trim(std::string_view text) {
    const auto is_space = [](char ch) {
        return ch == ' ' || ch == '\t' || ch == '\r' || ch == '\n' || ch == '\f' || ch == '\v';
    };
    while (!text.empty() && is_space(text.front())) {
        text.remove_prefix(1);
    }
    while (!text.empty() && is_space(text.back())) {
        text.remove_suffix(1);
    }
    return text;
}

/// The non-empty runs of `text` between any of the characters in `separators`, e.g.
/// split_words("a  b\tc") == {"a", "b", "c"}.
inline std::vector<std::string_view> split_words(std::string_view text,
                                                 std::string_view separators = " \t") {
    const auto is_separator = [&](char ch) {
        return separators.find(ch) != std::string_view::npos;
    };
    std::vector<std::string_view> words;
    std::size_t n = 0;
    while (n < text.size()) {
        while (n < text.size() && is_separator(text[n])) {
            ++n;
        }
        const std::size_t start = n;
        while (n < text.size() && !is_separator(text[n])) {
            ++n;
        }
        if (n > start) {
            words.push_back(text.substr(start, n - start));
        }
    }
    return words;
}

/// `text` as a number of type T when all of it is one, in std::from_chars syntax (no white space,
/// no leading '+'); nullopt otherwise, also when it is out of T's range.
template <typename T>
std::optional<T> parse_number(std::string_view text) {
    T value{};
    const auto result = std::from_chars(text.data(), text.data() + text.size(), value);
    if (text.empty() || result.ec != std::errc() || result.ptr != text.data() + text.size()) {
        return std::nullopt;
    }
    return value;
}

/// Shortest text that reads back as `value` (std::to_chars), for messages: 0.5, 1e+20, nan.
inline std::string format_number(double value) {
    char buffer[64];
    const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
    return std::string(buffer, result.ptr);
}

}  // namespace strata::detail
