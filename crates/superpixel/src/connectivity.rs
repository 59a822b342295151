//! Making every region one 4-connected piece, and relabelling to `0..k`.

/// Splits labels into 4-connected components and gives each its own label, in raster order,
/// except that components smaller than `min_size` pixels join the region of the pixel left of
/// (or above) their first pixel. Returns the new labels, contiguous from 0, and their count.
///
/// A merged fragment touches the region it joins at that first pixel, so every resulting region
/// is 4-connected.
pub(crate) fn enforce_connectivity(
    labels: &[u32],
    width: usize,
    height: usize,
    min_size: usize,
) -> (Vec<u32>, usize) {
    const UNSEEN: u32 = u32::MAX;
    let mut out = vec![UNSEEN; labels.len()];
    let mut next = 0u32;
    let mut component = Vec::new();
    let mut stack = Vec::new();
    for start in 0..labels.len() {
        if out[start] != UNSEEN {
            continue;
        }
        let original = labels[start];
        component.clear();
        stack.push(start);
        out[start] = next;
        while let Some(index) = stack.pop() {
            component.push(index);
            let neighbours = neighbours4(index, width, height);
            for n in neighbours.into_iter().flatten() {
                if out[n] == UNSEEN && labels[n] == original {
                    out[n] = next;
                    stack.push(n);
                }
            }
        }
        let (x, y) = (start % width, start / width);
        let adjacent = if x > 0 {
            Some(out[start - 1])
        } else if y > 0 {
            Some(out[start - width])
        } else {
            None
        };
        match adjacent {
            Some(label) if component.len() < min_size => component.iter().for_each(|&i| out[i] = label),
            _ => next += 1,
        }
    }
    (out, next as usize)
}

/// Renumbers labels to `0..k` in order of first appearance; returns them and k.
pub(crate) fn relabel(labels: &[u32]) -> (Vec<u32>, usize) {
    const UNSEEN: u32 = u32::MAX;
    let largest = labels.iter().copied().max().map_or(0, |l| l as usize + 1);
    let mut map = vec![UNSEEN; largest];
    let mut count = 0u32;
    let out = labels
        .iter()
        .map(|&label| {
            let new = &mut map[label as usize];
            if *new == UNSEEN {
                (*new, count) = (count, count + 1);
            }
            *new
        })
        .collect();
    (out, count as usize)
}

/// The 4-connected neighbours (left, right, up, down) of pixel `index` of a row-major
/// `width × height` grid, `None` past the border.
pub(crate) fn neighbours4(index: usize, width: usize, height: usize) -> [Option<usize>; 4] {
    let (x, y) = (index % width, index / width);
    [
        (x > 0).then(|| index - 1),
        (x + 1 < width).then(|| index + 1),
        (y > 0).then(|| index - width),
        (y + 1 < height).then(|| index + width),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splits_disconnected_pieces_and_merges_specks() {
        // Label 0 appears in two separate pieces; label 2 is a one-pixel speck inside label 1.
        #[rustfmt::skip]
        let labels = [
            0, 0, 1, 1, 1,
            0, 0, 1, 2, 1,
            1, 1, 1, 1, 1,
            0, 0, 0, 1, 1,
        ];
        let (out, count) = enforce_connectivity(&labels, 5, 4, 2);
        #[rustfmt::skip]
        assert_eq!(out, [
            0, 0, 1, 1, 1,
            0, 0, 1, 1, 1,
            1, 1, 1, 1, 1,
            2, 2, 2, 1, 1,
        ]);
        assert_eq!(count, 3);
    }

    #[test]
    fn relabel_is_contiguous_in_order_of_appearance() {
        assert_eq!(relabel(&[7, 7, 3, 9, 3]), (vec![0, 0, 1, 2, 1], 3));
    }
}
