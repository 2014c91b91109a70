// How a finished result file stores its series (output.compression, docs/scenes.md): the
// working file a run streams into is never compressed (rows are written one step at a time and
// must survive a kill); the finished file, written once when every case has ended, holds each
// series in chunks compressed with deflate after HDF5's byte shuffle, which readers (h5py,
// h5dump, subslip post) undo without being asked.
#pragma once

namespace subslip::model {

struct SeriesCompression {
  // 0: none; 1 ... 9: deflate (gzip) at that level. Level 1 gives nearly all of level 9's
  // saving on result series (full-precision doubles: about a fifth) in the least time
  // (docs/scenes.md, "Result file layout").
  int gzip_level = 1;
};

}  // namespace subslip::model
