#pragma once
// Result<T>: a value or a one-line human error message (cesium-native Result.h style).
// Bad files and bad input travel as Result; API misuse is an assert.
#include <cassert>
#include <string>
#include <utility>
#include <variant>

namespace seasonview {

/// The error side of a Result: one line naming the file (or input) and the problem.
struct Error {
    std::string message;
};

/// The first line of a library's error text, without trailing spaces and dots (error messages are one line).
inline std::string firstLine(std::string s) {
    if (const auto nl = s.find('\n'); nl != std::string::npos) s.resize(nl);
    while (!s.empty() && (s.back() == ' ' || s.back() == '.')) s.pop_back();
    return s;
}

/// Builds an Error "PATH: problem".
inline Error fileError(const std::string& path, const std::string& problem) { return Error{path + ": " + problem}; }

template <typename T> class [[nodiscard]] Result {
public:
    Result(T value) : m_v(std::in_place_index<0>, std::move(value)) {}
    Result(Error error) : m_v(std::in_place_index<1>, std::move(error)) {}

    bool ok() const { return m_v.index() == 0; }
    explicit operator bool() const { return ok(); }

    T& value() & {
        assert(ok() && "Result::value(): holds an error");
        return std::get<0>(m_v);
    }
    const T& value() const& {
        assert(ok() && "Result::value(): holds an error");
        return std::get<0>(m_v);
    }
    T&& value() && {
        assert(ok() && "Result::value(): holds an error");
        return std::get<0>(std::move(m_v));
    }
    T* operator->() { return &value(); }
    const T* operator->() const { return &value(); }
    T& operator*() & { return value(); }
    const T& operator*() const& { return value(); }

    const Error& error() const {
        assert(!ok() && "Result::error(): holds a value");
        return std::get<1>(m_v);
    }
    const std::string& message() const { return error().message; }

private:
    std::variant<T, Error> m_v;
};

/// Result of an operation that yields nothing but may fail.
struct Ok {};
using Status = Result<Ok>;

} // namespace seasonview
