#pragma once
// Scores of a segmentation against ground truth: the pixel confusion matrix and what follows from it, and crown
// centres matched to true trees. Plain C++.
#include <cstddef>
#include <cstdint>
#include <vector>

namespace seasonview {

/// Pixel counts of a binary segmentation against a binary truth (both: non-zero = treetop).
struct Confusion {
    std::uint64_t tp = 0, fp = 0, fn = 0, tn = 0;

    std::uint64_t excluded = 0; // pixels left out: a season (or the truth) has no data there

    /// Adds `n` pixels of a mask and the truth at the same place; where `scored` is given, only pixels where it is
    /// non-zero count (the others add to `excluded`).
    void add(const std::uint8_t* mask, const std::uint8_t* truth, std::size_t n, const std::uint8_t* scored = nullptr);
    Confusion& operator+=(const Confusion& o);

    std::uint64_t pixels() const { return tp + fp + fn + tn; }
    // Each is 0 when its denominator is 0 (as scikit-learn's zero_division=0).
    double precision() const; // tp / (tp + fp)
    double recall() const;    // tp / (tp + fn)
    double f1() const;        // 2 tp / (2 tp + fp + fn)
    double iou() const;       // tp / (tp + fp + fn)
};

/// A crown centre in the scene's local frame (metres east, north of the leaf-on image centre) and its radius.
struct CrownPoint {
    double x = 0.0, y = 0.0, radiusM = 0.0;
};

struct CentreScores {
    int detected = 0, truth = 0, matched = 0;
    double precision() const { return detected > 0 ? double(matched) / detected : 0.0; } // 0 when nothing detected
    double recall() const { return truth > 0 ? double(matched) / truth : 0.0; }
};

/// One-to-one matching of detected centres to true trees: a pair counts when the detection lies within the true
/// tree's radius of its centre; pairs are taken closest first (greedy), each detection and tree used once.
CentreScores matchCentres(const std::vector<CrownPoint>& detected, const std::vector<CrownPoint>& truth);

} // namespace seasonview
