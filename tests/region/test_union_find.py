import numpy as np

from limbctl.region.union_find import UnionFind


def test_pieces_join_count_their_size_and_a_long_chain_is_one():
    pieces = UnionFind(6)
    pieces.union(0, 1)
    root = pieces.union(2, 1)
    pieces.union(4, 5)
    assert pieces.size[root] == 3 and pieces.root(0) == pieces.root(2) == root
    assert pieces.union(0, 2) == root and pieces.size[root] == 3
    labels = pieces.labels()
    assert len(set(labels[[0, 1, 2]])) == 1 and labels[3] == 3
    assert labels[4] == labels[5] != labels[0]
    # a long chain is one piece
    n = 5000
    pieces = UnionFind(n)
    for i in range(n - 1):
        pieces.union(i + 1, i)
    assert np.all(pieces.labels() == pieces.root(0)) and pieces.size[pieces.root(0)] == n
