"""The detector's training set: random greenhouse views rendered with Cycles, boxes from the masks, COCO."""
