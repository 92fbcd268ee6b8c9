# The baseline of bench/remote: the least Cap'n Proto RPC that carries bytes there and back.
@0xed2d987c702cfafd;

interface Echo {
  echo @0 (data :Data) -> (data :Data);
}
