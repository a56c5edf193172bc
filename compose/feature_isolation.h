// FBPB feature isolation (thesis §3.4.4, docs/metatex.md): which texels of a tileable material
// are salient features (bricks, cobbles, flagstones) and which feature each belongs to.
//
// Automatic isolation, each step on the torus (the texture tiles, so a feature cut by the
// edge is one feature):
//  1. channel: the height (A) if it varies, else the luminance; smoothed by a wrap-around
//     Gaussian (smooth_sigma texels) so photo grain does not break features into specks, and
//     optionally taken relative to a wider Gaussian (background_sigma: removes shading);
//  2. threshold: Otsu's level, or the one given;
//  3. polarity: features are the compact, separated side, the background the connected
//     network (mortar, grout, soil between stones), whichever side is lighter. The side whose
//     largest 4-connected component holds the larger share of that side's texels is the
//     network; the shares are summed over the smoothing scale, half and twice it (grain
//     decides at the fine scale, shading at the coarse one; neither alone);
//  4. joints (cut_joints, experimental, off by default): thin lines of the background's
//     polarity (dark lines between light features) found by a Hessian ridge/valley measure at
//     1 and 2 texels with hysteresis (Otsu's level of the measure and 0.4 of it, keeping weak
//     stretches that continue strong ones). They cut the thresholded mask where a joint is too
//     faint for the global level, and the cells between joints that are more than 15 %
//     feature-coloured take back their shaded texels (a stone's dark side, a tile's shadowed
//     edge). Better counts on some photographs, worse on others, and it cuts one-texel bridges
//     itself (docs/metatex.md, "On real photographs");
//  5. pin-holes: background components other than the network and smaller than 1/16 of the
//     typical feature are filled; with joints cut, only those shorter than a quarter of its
//     side (a cut-off piece of joint is long and separates two features);
//  6. split: features touching through thin gaps or one-texel bridges are separated by a
//     distance transform and a marker-based watershed (OpenCV cv::distanceTransform,
//     cv::connectedComponents, cv::watershed; markers: where the distance is at least 0.4 of
//     the component's peak, or of the typical peak if lower), run on the texture padded
//     periodically and joined back across its edges;
//  7. specks: components smaller than min_feature_texels, or than speck_fraction of the
//     typical feature, are dropped.
// "Typical feature" is the area-weighted median component: the size of the component holding
// the median feature texel, which specks do not drag down.
//
// Limits: the threshold is global. Photographs whose features span the background's
// brightness (shaded stones, rough faces, faint joints) are not segmented reliably; the joint
// cut helps on some. See docs/metatex.md, "On real photographs". Use a hand-made mask for them.
//
// Thread-safety: pure functions.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "compose/image.h"

namespace tvt {

// Feature labels on a square, tileable texture: -1 = background, 0..count-1 = feature id.
struct FeatureLabels {
  int resolution = 0;
  std::vector<int32_t> labels;
  uint32_t count = 0;
};

struct IsolationOptions {
  enum class Channel { Auto, Luminance, Height };
  enum class Polarity { Auto, Light, Dark };  // Light: features are above the threshold
  Channel channel = Channel::Auto;   // Auto: height if A is not constant, else luminance
  double threshold = -1.0;           // in [0,1]; < 0: Otsu's method
  Polarity polarity = Polarity::Auto;
  double smooth_sigma = 1.0;         // texels, Gaussian before thresholding; 0: none
  // Texels: the value is taken relative to its neighbourhood, a Gaussian of this sigma
  // (removes slow shading before the threshold); 0: off.
  double background_sigma = 0.0;
  bool cut_joints = false;           // step 4 (experimental, off by default): cut along thin joint lines
  bool fill_holes = true;
  bool split_touching = true;        // distance transform + watershed
  uint32_t min_feature_texels = 8;   // absolute speck limit
  double speck_fraction = 0.1;       // relative speck limit, of the typical feature area
  uint32_t erode_texels = 0;         // optional erosion before labelling (the older splitter)
};

// What automatic isolation decided, for printing and the debug image.
struct IsolationReport {
  bool used_height = false;
  bool features_light = true;
  bool polarity_forced = false;
  double cut = 0.0;                  // threshold in 0..255 units of the (smoothed) channel
  double light_network_share = 0.0;  // largest component / side texels, per side (step 3; mean of the scales)
  double dark_network_share = 0.0;
  uint32_t joint_texels = 0;         // step 4: texels on joint lines
  uint32_t reclaimed_texels = 0;     // step 4: background-coloured texels given to feature cells
  uint32_t components = 0;           // feature components before splitting
  uint32_t split_added = 0;          // features the watershed added
  uint32_t holes_filled = 0;         // pin-holes (components)
  uint32_t specks_dropped = 0;
  uint32_t speck_limit = 0;          // texels: smaller components were dropped
  double smooth_sigma = 0.0;         // the scales used
  double background_sigma = 0.0;
  // Per texel: 0 plain, 1 filled pin-hole, 2 dropped speck, 3 watershed split line.
  std::vector<uint8_t> marks;
  std::string summary() const;
};

FeatureLabels isolate_features(const ImageRGBA8& albedo, const IsolationOptions& options,
                               IsolationReport* report = nullptr);
// A hand-made mask (non-zero = feature): connected components on the torus, specks dropped.
FeatureLabels labels_from_mask(const ImageGray8& mask, uint32_t min_feature_texels);
// The other way, for editing by hand (`terravt metatex --mask-out`): 255 on features, 0 on the
// background, and 0 on the texels of a feature that touch (4-neighbours, on the torus) a feature
// of a lower label, so that features the isolation split stay apart in the mask. Drawn on the
// image as given, `width` x `height`, from which labels_from_mask() and a scene's `fbpb.mask`
// read the material's texels by nearest texel (material_image.h, resample_mask_nearest()):
// each pixel is 0 if any texel that reads it is 0 (a smaller image keeps the splits), and a
// pixel no texel reads takes the texel under it. At the material's own size or larger,
// labels_from_mask() gives the same features less the split texels, unless a split line cuts a
// feature through a one-texel neck or leaves it below the speck limit.
ImageGray8 mask_from_labels(const FeatureLabels& labels, int width, int height);

}  // namespace tvt
