// Contact candidates against the O(n^2) reference (placeholder, filled in below).
